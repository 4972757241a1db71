"""
PyBullet's reading of the generated URDF: frames and dynamics.

Link frames are the DH model's (eq. 4-7), and computed torque from PyBullet's own inverse
dynamics holds the arm (docs/design.md §5: no hidden damping or motors).
"""

import math

from ibvs_model import fiducial_points, IRB4600, joint_frames
from ibvs_sim.world import World
import numpy as np
import pytest


def _rot_z(angle):
    tf = np.eye(4)
    tf[:2, :2] = [[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]]
    return tf


@pytest.mark.parametrize('params', [IRB4600, IRB4600.scaled(1.15, 0.85)],
                         ids=['paper', 'scaled'])
def test_link_frames_equal_fk_on_100_random_configurations(params):
    """Every link frame, tool0 = {E} and both marker centres, to 1e-6 m and 1e-6 rad."""
    world = World(params, render=False)
    try:
        offsets = params.dh_table()[:, 3]
        rng = np.random.default_rng(11)
        worst_pos = worst_rot = 0.0
        for _ in range(100):
            q = rng.uniform(params.q_min, params.q_max)
            world.reset(q)
            dh = joint_frames(q, params)
            expected = {f'link_{i}': dh[i - 1] @ _rot_z(q[i - 1] + offsets[i - 1])
                        for i in range(1, 7)}
            expected['tool0'] = dh[6]
            for name, tf in expected.items():
                got = world.link_pose(name)
                worst_pos = max(worst_pos, np.abs(got[:3, 3] - tf[:3, 3]).max())
                worst_rot = max(worst_rot, np.abs(got[:3, :3] - tf[:3, :3]).max())
            markers = fiducial_points(q, params)
            for k in (1, 2):
                got = world.link_pose(f'marker_{k}')[:3, 3]
                worst_pos = max(worst_pos, np.abs(got - markers[k - 1]).max())
        # PyBullet reports link states in single precision: ~1e-7 m is its floor.
        assert worst_pos < 1e-6 and worst_rot < 1e-6, (worst_pos, worst_rot)
    finally:
        world.close()


HOLD_CONFIGS = np.radians([
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [30.0, 40.0, -20.0, 60.0, -45.0, 90.0],
    [-120.0, -60.0, 50.0, -150.0, 100.0, -300.0],
    [170.0, 130.0, -170.0, 380.0, -110.0, 10.0],
    [-45.0, 90.0, -90.0, 0.0, 60.0, 200.0],
])


@pytest.fixture(scope='module')
def physics():
    w = World(render=False)
    try:
        yield w
    finally:
        w.close()


def _run(world, q0, steps, torque_fn):
    world.reset(q0)
    for _ in range(steps):
        world.step(torque_fn())
    return world.joint_state()


def test_computed_torque_holds_the_arm_for_one_second(physics):
    """Torque ID(q, qd, 0) every step: drift < 1e-6 rad over 1 s in 5 configurations."""
    steps = int(round(1.0 / physics.dt))
    for q0 in HOLD_CONFIGS:
        def computed_torque():
            q, qd = physics.joint_state()
            return physics.inverse_dynamics(q, qd, np.zeros(6))
        q, qd = _run(physics, q0, steps, computed_torque)
        assert np.abs(q - q0).max() < 1e-6, np.abs(q - q0).max()
        assert np.abs(qd).max() < 1e-6


def test_without_torque_the_arm_falls(physics):
    """The hold above is the torque's doing: with zero torque gravity moves the arm."""
    q, _ = _run(physics, HOLD_CONFIGS[1], 100, lambda: np.zeros(6))
    assert np.abs(q - HOLD_CONFIGS[1]).max() > 1e-3


def test_computed_torque_follows_a_commanded_acceleration(physics):
    """ID(q, qd, a) gives acceleration a: the plant is the double integrator of eq. (27)."""
    accel = np.array([1.0, -2.0, 0.5, 3.0, -1.5, 4.0])
    steps = 200
    q0 = HOLD_CONFIGS[1]

    def computed_torque():
        q, qd = physics.joint_state()
        return physics.inverse_dynamics(q, qd, accel)
    q, qd = _run(physics, q0, steps, computed_torque)
    t = steps * physics.dt
    # Semi-implicit Euler: qd_n = n h a, q_n = q_0 + h^2 a n (n + 1) / 2.
    assert np.allclose(qd, accel * t, atol=1e-6)
    assert np.allclose(q, q0 + accel * physics.dt ** 2 * steps * (steps + 1) / 2, atol=1e-6)


def test_hold_torque_stops_a_moving_arm_in_one_step(physics):
    physics.reset(HOLD_CONFIGS[2], qd=[0.5, -0.3, 0.8, -1.0, 0.6, 2.0])
    q0, _ = physics.joint_state()
    for _ in range(3):
        physics.step(physics.hold_torque())
        q, qd = physics.joint_state()
        assert np.abs(q - q0).max() < 1e-9
        assert np.abs(qd).max() < 1e-9
