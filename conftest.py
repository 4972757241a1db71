"""Isolate each test process on its own ROS domain, on the loopback interface only."""


def pytest_configure(config):
    """
    Put this process (the controller, or a pytest-xdist worker) on its own ROS domain.

    Runs before any test module is collected, hence before any rclpy Context exists:
    :func:`ibvs_testing.isolation.isolate` takes the domain through the lock every run takes
    (:func:`ibvs_bringup.domains.claim`: the explicit ``ROS_DOMAIN_ID``, else the highest
    free domain of ``IBVS_ROS_DOMAINS``, away from domain 0 where a graph that takes no lock
    is likely) and holds it while the process lives, and the graph's
    Fast DDS profiles are loaded as every node loads them (:func:`ibvs_common.dds.configure`).
    A domain that another run holds, or a ``ROS_DOMAIN_ID`` ROS must not use, stops the
    session with the reason.
    """
    try:
        from ibvs_bringup import domains
        from ibvs_common import dds
        from ibvs_testing.isolation import isolate
    except ImportError:  # the workspace is not sourced: only the linters can run
        return
    import pytest

    def take(environ):
        # The highest free domain, but not 101: on this project's machine the lockstep's
        # camera test received frames twice on domain 101 and never on 60-100 (Fast DDS's
        # ports for domain 101 begin 100 below Linux's ephemeral range).
        low, high = domains.pool(environ)
        top = 100 if high == 101 and low < 101 else high
        return domains.claim(environ, pool=(low, top), from_top=True)

    try:
        isolate(take=take, held_env=domains.HELD_ENV)
    except (domains.DomainBusy, domains.DomainError) as exc:
        raise pytest.UsageError(f'no ROS domain for this test process: {exc}') from None
    dds.configure()
