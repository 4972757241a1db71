"""
The references a real-cell run sent, read back from its bag, obey the arm's limits.

`ibvs run real_cell` through joint_trajectory_controller's topic (each window carries the
planned positions, velocities and accelerations one command period apart): every point
within the joint ranges, every velocity within the speed cap, every acceleration within
the drive's limits, and the jerk between a window's points within the drive's jerk limits;
and the first points of the windows, which the arm follows, at most the cap apart per
second between two windows. What the property test of the shaper holds for random starts,
targets and corrections, here for what went out of a running graph.
"""

from pathlib import Path

from ibvs_common.conversions import duration_ns, stamp_ns
from ibvs_experiments import cli
from ibvs_model import IRB4600
from ibvs_model.drive import ACCELERATION_LIMITS, JERK_LIMITS, SPEED_LIMITS
import numpy as np
import pytest
from rosbags.highlevel import AnyReader

TOPIC = '/joint_trajectory_controller/joint_trajectory'
CAP_DEG_S = 60.0


def windows(bag):
    """Return (stamp ns, joint names, positions, velocities, accelerations, times) per message."""
    out = []
    with AnyReader([Path(bag)]) as reader:
        connections = [c for c in reader.connections if c.topic == TOPIC]
        for connection, _, raw in reader.messages(connections=connections):
            msg = reader.deserialize(raw, connection.msgtype)
            points = msg.points
            out.append((stamp_ns(msg.header.stamp), list(msg.joint_names),
                        np.array([p.positions for p in points]),
                        np.array([p.velocities for p in points]),
                        np.array([p.accelerations for p in points]),
                        np.array([duration_ns(p.time_from_start) for p in points])))
    return out


@pytest.mark.slow
def test_every_reference_in_a_real_cell_bag_obeys_the_limits(installed_workspace, tmp_path):
    out = tmp_path / 'run'
    code = cli.main(['run', 'real_cell', '--duration', '1.5', '-o', str(out),
                     '-p', 'position_command_type:=joint_trajectory',
                     '-p', f'max_joint_speed_deg_s:={CAP_DEG_S}'])
    assert code == 0
    got = windows(out / 'bag')
    assert len(got) >= 20, 'too few reference windows recorded'
    cap = np.minimum(np.asarray(SPEED_LIMITS), np.radians(CAP_DEG_S))
    accel, jerk = np.asarray(ACCELERATION_LIMITS), np.asarray(JERK_LIMITS)
    low, high = np.asarray(IRB4600.q_min), np.asarray(IRB4600.q_max)
    moved = 0.0
    firsts = []
    for stamp, names, pos, vel, acc, times in got:
        order = [names.index(f'joint_{i}') for i in range(1, 7)]
        pos, vel, acc = pos[:, order], vel[:, order], acc[:, order]
        assert np.all(pos >= low) and np.all(pos <= high)
        assert np.all(np.abs(vel) <= cap + 1e-9)
        assert np.all(np.abs(acc) <= accel + 1e-9)
        dt = np.diff(times) * 1e-9
        assert np.all(dt > 0.0)
        assert np.all(np.abs(np.diff(acc, axis=0)) <= jerk * dt[:, None] * (1 + 1e-6) + 1e-9)
        moved = max(moved, float(np.max(np.abs(vel))))
        firsts.append((stamp, pos[0]))
    assert moved > 0.5 * np.radians(CAP_DEG_S), 'the arm should have been slewing at the cap'
    for (t0, q0), (t1, q1) in zip(firsts, firsts[1:]):
        assert t1 > t0
        assert np.all(np.abs(q1 - q0) <= cap * (t1 - t0) * 1e-9 + 1e-9)
