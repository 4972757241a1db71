"""
The test fixtures and helpers every package's tests share (imported by tests only).

Each test directory's ``conftest.py`` imports the fixtures it uses from here, so they work
both from the repository root (``make test``, ``pytest``) and under ``colcon test``, which
runs each package's tests on their own. Importing this module also puts the test process on
its own ROS domain, on the loopback interface only (:func:`isolate`).

- :func:`context`: a private, initialised rclpy Context on this process's domain;
- :func:`executor_of`: executors of nodes in that context, torn down after the test;
- :func:`domain_id`: that domain, for child processes;
- :func:`spin_until`: spin an executor until a condition holds (a deadline guards a hang;
  tests wait on conditions, never on wall-clock time);
- :func:`world`: the paper's robot in a PyBullet world (module scope);
- :func:`camera` / :func:`default_camera`: the ZED 2 at the default pose.
"""

import os
import time

from ibvs_model import look_at, paper, StereoCamera, StereoIntrinsics
import pytest
import rclpy

from . import dds

#: Environment variable that says the process's ROS domain was chosen by :func:`isolate`.
DOMAIN_SET_BY = 'IBVS_TEST_DOMAIN_SET_BY'
#: Default deadline of :func:`spin_until` (seconds): only a guard against a hang.
DEADLINE_S = 60.0


def isolate():
    """
    Give this test process its own ROS domain and keep discovery on localhost.

    Parallel test runs (two CI jobs, a developer's shell, other agents' graphs) must not
    hear each other. An explicit ``ROS_DOMAIN_ID`` in the environment wins. Also loads the
    graph's Fast DDS profiles (:mod:`ibvs_common.dds`), as every node does.

    Under pytest-xdist (``make test`` runs two workers) the workers inherit the environment
    of the controlling pytest process, which set its own domain here: each worker then takes
    a domain of its own (:data:`DOMAIN_SET_BY` marks a domain chosen here, not by the
    user), else the workers' nodes would hear each other and their graph runs would contend
    for one domain's lock.
    """
    worker = os.environ.get('PYTEST_XDIST_WORKER', '')
    chosen_here = os.environ.get(DOMAIN_SET_BY) == 'isolate'
    if 'ROS_DOMAIN_ID' not in os.environ or (worker and chosen_here):
        index = int(worker[2:]) if worker.startswith('gw') and worker[2:].isdigit() else 0
        # 1..100: inside the range ROS 2 documents as safe on Linux; two workers (gw0, gw1)
        # of one run get neighbouring domains.
        os.environ['ROS_DOMAIN_ID'] = str(1 + (2 * (os.getppid() % 50) + index) % 100
                                          if worker else 1 + os.getpid() % 100)
        os.environ[DOMAIN_SET_BY] = 'isolate'
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    dds.configure()


isolate()


def domain_id_of_process():
    """Return the ROS domain of this test process (``ROS_DOMAIN_ID``, set by :func:`isolate`)."""
    return int(os.environ['ROS_DOMAIN_ID'])


@pytest.fixture(scope='session')
def domain_id():
    """Return the ROS domain of this test process, e.g. for the environment of a child."""
    return domain_id_of_process()


@pytest.fixture
def context():
    """Yield a private, initialised rclpy Context (as rclpy's own tests do)."""
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=domain_id_of_process())
    try:
        yield ctx
    finally:
        rclpy.try_shutdown(context=ctx)


@pytest.fixture
def executor_of(context):
    """
    Yield make(*nodes): a SingleThreadedExecutor of ``context`` spinning ``nodes``.

    At teardown every executor made is shut down and its nodes destroyed.
    """
    from rclpy.executors import SingleThreadedExecutor
    made = []

    def make(*nodes):
        executor = SingleThreadedExecutor(context=context)
        for node in nodes:
            executor.add_node(node)
        made.append((executor, nodes))
        return executor

    yield make
    for executor, nodes in made:
        executor.shutdown()
        for node in nodes:
            node.destroy_node()


def spin_until(executor, condition, deadline_s=DEADLINE_S, what='condition'):
    """Spin ``executor`` until ``condition()`` is true; fail naming ``what`` at the deadline."""
    end = time.monotonic() + deadline_s
    while not condition():
        assert time.monotonic() < end, f'timed out waiting for {what}'
        executor.spin_once(timeout_sec=0.05)


@pytest.fixture(scope='module')
def world():
    """Yield the paper's robot in a PyBullet world with the default renderer ('auto')."""
    from ibvs_sim.world import World  # ibvs_sim depends on ibvs_common, not the reverse
    w = World()
    try:
        yield w
    finally:
        w.close()


def default_camera(resolution='HD720'):
    """Return the ZED 2 at ``resolution`` at the default pose (docs/design.md §5)."""
    return StereoCamera(StereoIntrinsics.zed2(resolution),
                        look_at(paper.CAMERA_EYE, paper.CAMERA_LOOK_AT))


@pytest.fixture(scope='module')
def camera():
    """Return the ZED 2 at HD720 at the default pose (docs/design.md §5)."""
    return default_camera('HD720')
