"""Fixtures of the ibvs_viz tests: the shared ones (ibvs_common.testing)."""

from ibvs_common.testing import context, default_camera, executor_of  # noqa: F401
