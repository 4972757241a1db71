"""Isolate each test process on its own ROS domain, on the loopback interface only."""

try:  # the shared fixtures' module isolates the process on import (ibvs_common.testing)
    from ibvs_common import testing  # noqa: F401
except ImportError:  # the workspace is not sourced: only the linters can run
    pass
