"""Experiments on the node graph: run, analyse, study, report, bench (above ibvs_bringup)."""
