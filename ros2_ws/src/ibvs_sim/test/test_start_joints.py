"""A task's start: the simulator starts from start_joints as given, or from the scenario."""

from ibvs_model import forward_kinematics, inverse_kinematics, paper, pose_error
from ibvs_sim.node_params import SimConfig
from ibvs_sim.simulator import ConfigError, Simulator
import numpy as np
import pytest


def test_start_joints_are_the_true_start_angles_and_empty_keeps_the_scenario():
    q = (0.2, 0.1, 0.5, 0.4, 0.7, 3.2)
    sim = Simulator(SimConfig.make(start_joints=q), render=False)
    try:
        assert np.array_equal(sim.q_start, q)
        assert max(sim.start_residual) == 0.0
    finally:
        sim.world.close()
    sim = Simulator(SimConfig.make(scenario=2), render=False)
    try:
        expected = inverse_kinematics(paper.scenario_start_pose(2), sim.params)
        assert np.array_equal(sim.q_start, expected)
        assert max(pose_error(forward_kinematics(sim.q_start), paper.scenario_start_pose(2))) \
            < 1e-9
    finally:
        sim.world.close()


def test_start_joints_of_another_length_are_refused_naming_them():
    with pytest.raises(ConfigError, match='start_joints'):
        Simulator(SimConfig.make(start_joints=(0.0, 0.1)), render=False)


def test_a_start_pose_is_solved_as_the_teach_pose_is():
    """The tool held at the target (start_at_target): the same angles as the teach pair's."""
    target = paper.target_pose()
    sim = Simulator(SimConfig.make(), render=False, start_pose=target, teach_pose=None)
    try:
        assert np.array_equal(sim.q_start, inverse_kinematics(target, sim.params))
        assert max(sim.start_residual) < 1e-9
    finally:
        sim.world.close()
