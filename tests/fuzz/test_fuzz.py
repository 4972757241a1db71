"""
Bad input into every subscribed topic of every node: survival, counting, recovery.

Each node runs in-process in a private Context (:mod:`.rigs`); every case of
:mod:`.cases` is sent to it in turn and checked (:mod:`.harness`): no exception out of a
callback, a ``rejected[<topic>: <reason>]`` count for each bad message (for a valid but
costly one, its answer), the node acting on the next valid input, and nothing non-finite in
anything it publishes. The per-node table (cases / crashes / stuck / accepted silently /
non-finite outputs) is printed at the end of the session.
"""

import pytest

from . import rigs
from .harness import assert_clean, run_all

RIGS = {
    'sim_node': rigs.SimRig,
    'feature_node': rigs.FeatureRig,
    'feature_node[HD720]': lambda context: rigs.FeatureRig(context, 'HD720'),
    'adaptive_feedback_node': rigs.AdaptiveFeedbackRig,
    'feedforward_node': rigs.FeedforwardRig,
    'joint_controller_node': rigs.JointControllerRig,
    'sim_node[position]': rigs.SimPositionRig,
    'sim_node[trajectory]': lambda context: rigs.SimPositionRig(context, 'joint_trajectory'),
    'joint_controller_node[position]': rigs.JointControllerPositionRig,
    'viz_node': rigs.VizRig,
    'robot_state_node': rigs.RobotStateRig,
}


@pytest.mark.parametrize('name', sorted(RIGS))
def test_fuzz_node(context, name):
    rig = RIGS[name](context)
    try:
        rig.setup()
        if name != 'feedforward_node':
            assert rig.recovered(), f'{name} does not act on valid input before any fault'
        outcomes = run_all(name, rig, rig.cases())
        if name == 'feedforward_node':
            # Its one action comes last: the first valid state after every bad one.
            assert rig.spin_until(rig.valid_step()), 'feedforward never started'
        assert_clean(rig, outcomes)
        assert rig.published_finite(), f'{name} published a non-finite value'
    finally:
        rig.close()
