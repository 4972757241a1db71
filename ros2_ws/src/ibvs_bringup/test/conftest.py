"""Fixtures of the ibvs_bringup tests: the shared ones (ibvs_common.testing)."""

from ibvs_common.testing import context  # noqa: F401
