"""Scenarios, runner, recorder, metrics, plots and report of the paper's section 5."""
