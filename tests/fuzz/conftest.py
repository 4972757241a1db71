"""The fuzz suite's fixtures, and its table at the end of the session."""

from ibvs_testing.fixtures import context  # noqa: F401 (the shared fixture)

from .harness import TABLES

HEADER = (f"{'node':32s} {'cases':>5s} {'crashes':>7s} {'stuck':>5s} {'accepted silently':>17s}"
          f" {'non-finite outputs':>18s}")


def pytest_terminal_summary(terminalreporter):
    """Print the per-node table: cases / crashes / stuck / accepted silently / non-finite."""
    if TABLES:
        terminalreporter.section('fuzz: bad input into every subscribed topic, bad parameters')
        terminalreporter.write_line(HEADER)
        for line in TABLES:
            terminalreporter.write_line(line)
