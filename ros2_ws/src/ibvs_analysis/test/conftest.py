"""Fixtures of the ibvs_analysis tests: the shared ones (ibvs_testing)."""

from ibvs_testing.fixtures import context, executor_of  # noqa: F401
