"""Experiments on the node graph: run, study, report, bench, the cell (above ibvs_analysis)."""
