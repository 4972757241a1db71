"""
A run's bag read back, by the name this package's benches still import it under.

The reading is :mod:`ibvs_analysis.analysis`; ``make bench`` (:mod:`.bench`) and the nodes'
bench (:mod:`.nodes_bench`) take these names from here.
"""

from ibvs_analysis.analysis import (feature_errors, load_joints,  # noqa: F401 (re-exported)
                                    load_run, node_timings, PARAMS_KEY)
