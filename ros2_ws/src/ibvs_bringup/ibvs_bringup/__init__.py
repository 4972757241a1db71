"""Bring up the node graph of the paper's section 5: its description, processes, recorder."""
