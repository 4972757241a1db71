"""Fixtures of the ibvs_common tests: the shared ones (ibvs_testing)."""

from ibvs_testing.fixtures import context  # noqa: F401
