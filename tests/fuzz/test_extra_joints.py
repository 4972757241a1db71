"""
/joint_states as joint_state_broadcaster publishes it on a real cell, into every node.

joint_state_broadcaster publishes every joint of every hardware (an arm's track, a gripper)
in its own order. Each node that reads /joint_states runs in its rig (:mod:`.rigs`) with
every joint state it is given rewritten: an extra joint ``track_1`` (its velocity NaN, as
the broadcaster fills an interface that a joint lacks) and the arm's joints in a shuffled
order. The node must act on each state as on the plain one (the same outputs where the rig
records them), reject none, and say once on /diagnostics which joint it ignores.
"""

from ibvs_common import contract
from ibvs_common.conversions import read_joints
import numpy as np
import pytest
from sensor_msgs.msg import JointState

from . import rigs

#: Where each arm joint goes in the rewritten message; the extra joint goes in between.
SHUFFLE = [4, 0, 5, 2, 3, 1]
EXTRA = 'track_1'

RIGS = {
    'feature_node': rigs.FeatureRig,
    'adaptive_feedback_node': rigs.AdaptiveFeedbackRig,
    'feedforward_node': rigs.FeedforwardRig,
    'joint_controller_node': rigs.JointControllerRig,
    'joint_controller_node[position]': rigs.JointControllerPositionRig,
    'viz_node': rigs.VizRig,
}


def with_extra_joint(msg):
    """Return ``msg`` (six arm joints) with ``track_1`` added and the joints shuffled."""
    out = JointState(header=msg.header)
    names = [msg.name[i] for i in SHUFFLE]
    out.name = names[:3] + [EXTRA] + names[3:]
    for field, extra in (('position', 0.75), ('velocity', float('nan')), ('effort', 0.0)):
        values = list(getattr(msg, field))
        if values:
            shuffled = [values[i] for i in SHUFFLE]
            setattr(out, field, shuffled[:3] + [extra] + shuffled[3:])
    np.testing.assert_array_equal(read_joints(out), read_joints(msg))  # the same state
    return out


def rewrite_joint_states(rig):
    """Make every /joint_states that ``rig`` delivers carry the extra joint, shuffled."""
    deliver = rig.deliver

    def rewritten(topic, msg):
        if topic == contract.JOINT_STATES:
            msg = with_extra_joint(msg)
        return deliver(topic, msg)

    rig.deliver = rewritten


def _outputs(rig):
    """Return what the rig recorded of the node's outputs, as comparable arrays."""
    if isinstance(rig, rigs.JointControllerRig):
        return [read_joints(m, 'effort') for m in rig.efforts]
    if isinstance(rig, rigs.AdaptiveFeedbackRig):
        return [read_joints(m) for m in rig.out]
    if isinstance(rig, rigs.FeedforwardRig):
        return [np.array([p.positions for p in m.points]) for m in rig.trajectories]
    return None


def _run(context, name, extra, steps=4):
    rig = RIGS[name](context)
    try:
        if extra:
            rewrite_joint_states(rig)
        rig.setup()
        for _ in range(1 if name == 'feedforward_node' else steps):
            assert rig.spin_until(rig.valid_step()), f'{name} did not act on a joint state'
        return rig.reasons(contract.JOINT_STATES), rig.diagnostics.values, _outputs(rig)
    finally:
        rig.close()


@pytest.mark.parametrize('name', sorted(RIGS))
def test_extra_joint_is_ignored_and_the_arm_read_by_name(context, name):
    rejected, values, outputs = _run(context, name, extra=True)
    assert not rejected, f'{name} rejected /joint_states: {dict(rejected)}'
    assert values.get('ignored_joints') == EXTRA
    plain_rejected, plain_values, plain_outputs = _run(context, name, extra=False)
    assert 'ignored_joints' not in plain_values
    if outputs is not None:
        assert len(outputs) == len(plain_outputs) > 0
        for got, want in zip(outputs, plain_outputs):
            np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize('name', ['joint_controller_node', 'viz_node'])
def test_a_missing_arm_joint_is_still_rejected(context, name):
    rig = RIGS[name](context)
    try:
        rig.setup()
        msg = with_extra_joint(rigs.joint_state(rig.next_ns(), rigs.Q0, np.zeros(6)))
        keep = [i for i, n in enumerate(msg.name) if n != 'joint_3']
        for field in ('name', 'position', 'velocity', 'effort'):
            if len(getattr(msg, field)):
                setattr(msg, field, [getattr(msg, field)[i] for i in keep])
        rig.deliver(contract.JOINT_STATES, msg)
        assert rig.reasons(contract.JOINT_STATES) == {'missing joints': 1}
    finally:
        rig.close()
