"""The lens worker renders, in its own process, exactly what the simulator's world would."""

from ibvs_model import inverse_kinematics, paper
from ibvs_sim import lens_worker
from ibvs_sim.lens_worker import LensWorkerError
from ibvs_sim.rendering import lens_poses
from ibvs_sim.world import DEFAULT_FOCUS_SUPERSAMPLING, World
import numpy as np
import pytest


@pytest.fixture(scope='module')
def parallel_world():
    """Yield a world that renders its right lens in a worker process."""
    w = World(lens_worker=True)
    try:
        yield w
    finally:
        w.close()


def _move(world, steps):
    """Drive the arm for ``steps`` physics steps with a constant joint acceleration."""
    for _ in range(steps):
        q, qd = world.joint_state()
        world.step(world.inverse_dynamics(q, qd, np.full(6, 2.0)))


def test_the_worker_draws_the_same_right_image_as_this_process(parallel_world, camera):
    world = parallel_world
    world.reset(inverse_kinematics(paper.scenario_start_pose(1)))
    _move(world, 40)  # a state reached by dynamics, not by reset
    spheres = world.marker_spheres()
    args = (camera.intrinsics, 1, tuple(spheres), DEFAULT_FOCUS_SUPERSAMPLING)
    left, right = world.render_stereo(camera, 1, spheres, DEFAULT_FOCUS_SUPERSAMPLING)
    pose_left, pose_right = lens_poses(camera)
    assert np.array_equal(left, world.render_lens(pose_left, *args))
    local_right = world.render_lens(pose_right, *args)
    assert np.array_equal(right, local_right)
    assert not np.array_equal(left, right)  # two viewpoints: the check can fail


def test_a_worker_killed_by_a_signal_is_started_again_and_draws_the_same_image(camera):
    # A crash below us (docs/studies.md): SIGKILL stands in for the SIGSEGV seen.
    world = World(renderer='tiny', lens_worker=True)
    try:
        first = world.render_stereo(camera)
        world._lens_worker._process.kill()
        world._lens_worker._process.wait(timeout=10.0)
        again = world.render_stereo(camera)
        assert np.array_equal(first[1], again[1]) and np.array_equal(first[0], again[0])
        assert len(world.lens_worker_restarts) == 1
        assert 'killed by SIGKILL' in world.lens_worker_restarts[0]
        assert world._lens_worker._process.poll() is None  # the new one serves
    finally:
        world.close()


def test_a_worker_that_dies_again_and_again_is_an_error_not_a_hang(camera, monkeypatch):
    monkeypatch.setattr(lens_worker, 'MAX_RESTARTS', 0)
    world = World(renderer='tiny', lens_worker=True)
    try:
        world._lens_worker._process.kill()
        world._lens_worker._process.wait(timeout=10.0)
        with pytest.raises(LensWorkerError, match='0 restart'):
            world.render_stereo(camera)
    finally:
        world.close()


def test_a_worker_stopped_by_sigterm_is_not_started_again(camera):
    # SIGTERM asks a process to stop (a run ending): not a crash.
    world = World(renderer='tiny', lens_worker=True)
    try:
        world._lens_worker._process.terminate()
        world._lens_worker._process.wait(timeout=10.0)
        with pytest.raises(LensWorkerError, match='exit code -15'):
            world.render_stereo(camera)
        assert world.lens_worker_restarts == ()
    finally:
        world.close()


def test_a_worker_that_ends_by_itself_is_not_started_again(camera):
    world = World(renderer='tiny', lens_worker=True)
    try:
        world._lens_worker._conn.send(None)  # what close() says: the worker returns, code 0
        world._lens_worker._process.wait(timeout=10.0)
        with pytest.raises(LensWorkerError, match='exit code 0'):
            world.render_stereo(camera)
        assert world.lens_worker_restarts == ()
    finally:
        world.close()


def test_close_ends_the_worker_process(camera):
    world = World(renderer='tiny', lens_worker=True)
    process = world._lens_worker._process
    world.render_stereo(camera)
    world.close()
    assert process.poll() is not None


def test_sigint_is_left_to_the_simulator(parallel_world, camera):
    """Ctrl-C signals the whole process group: the worker keeps serving until it is closed."""
    import signal
    import time
    world = parallel_world
    process = world._lens_worker._process
    process.send_signal(signal.SIGINT)
    time.sleep(0.5)
    assert process.poll() is None
    left, right = world.render_stereo(camera)
    assert left.shape == right.shape
