"""Isolate each test process on its own ROS domain, on the loopback interface only."""

import os

# Parallel test runs (two CI jobs, a developer's shell) must not hear each other.
os.environ.setdefault('ROS_DOMAIN_ID', str(1 + os.getpid() % 100))
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')

try:  # the graph's Fast DDS profiles (ibvs_common.dds), when the workspace is sourced
    from ibvs_common import dds
except ImportError:
    pass
else:
    dds.configure()
