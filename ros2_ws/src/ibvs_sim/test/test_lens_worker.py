"""The lens worker renders, in its own process, exactly what the simulator's world would."""

from ibvs_model import inverse_kinematics, paper
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


def test_a_dead_worker_is_an_error_not_a_hang(camera):
    world = World(renderer='tiny', lens_worker=True)
    try:
        world._lens_worker._process.kill()
        world._lens_worker._process.wait(timeout=10.0)
        with pytest.raises(LensWorkerError):
            world.render_stereo(camera)
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
