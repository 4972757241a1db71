"""Isolate each test process on its own ROS domain, on the loopback interface only."""


def pytest_configure(config):
    """
    Put this process (the controller, or a pytest-xdist worker) on its own ROS domain.

    Runs before any test module is collected, hence before any rclpy Context exists:
    :func:`ibvs_testing.isolation.isolate` chooses the domain, and the graph's Fast DDS
    profiles are loaded as every node loads them (:func:`ibvs_common.dds.configure`).
    """
    try:
        from ibvs_common import dds
        from ibvs_testing.isolation import isolate
    except ImportError:  # the workspace is not sourced: only the linters can run
        return
    isolate()
    dds.configure()
