"""
The feature node's stereo pairing (ibvs_vision.stereo_pairing) by property, without rclpy.

Order of arrival does not change the frames published, memory stays bounded under a flood,
a missing input is named, and frames that can never be complete are dropped with a reason.
Plain functions without fixtures, so that the first test can run them all in a process
where rclpy is never imported.
"""

import itertools
import random

from ibvs_common.sync import Rejection
from ibvs_common.timing import frame_stamp_ns
from ibvs_testing.plain import interleave, run_without_rclpy
from ibvs_vision.stereo_pairing import Drop, Ready, StereoPairer, Wait

MS = 1_000_000
DT = MS                 # 1 kHz physics
CAM = 33_333_333        # 30 Hz camera: frames stamped 0, 34, 67, 100 ms, ...


def test_stereo_pairing_tests_run_without_rclpy():
    """The rule and these tests load and pass with no rclpy imported."""
    assert run_without_rclpy(__file__, 'test_stereo_pairing_tests_run_without_rclpy') > 0


# -- StereoPairer (feature node) -------------------------------------------------------------

def stereo_world(frames=5):
    stamps = [frame_stamp_ns(n, CAM, DT) for n in range(frames)]
    return ([('left', t) for t in stamps], [('right', t) for t in stamps],
            [('joints', t) for t in range(0, stamps[-1] + 2 * DT, DT)])


def run_stereo(events, blocker=None, stale_timeout_ns=500 * MS):
    pairer = StereoPairer(stale_timeout_ns=stale_timeout_ns, history_ns=2000 * MS)
    out = []
    for kind, t_ns in events:
        if kind == 'joints':
            pairer.offer_joints(t_ns, f'q{t_ns}')
            rejection = None
        elif kind == 'bad joints':
            pairer.offer_bad_joints(t_ns, 'NaN')
            rejection = None
        else:
            rejection = pairer.offer_image(kind, t_ns, f'{kind}{t_ns}')
        if rejection is not None:
            out.append(('rejected', kind, t_ns, rejection.reason))
        for event in pairer.poll(blocker):
            if isinstance(event, Ready):
                pairer.published(event.t_ns)
                out.append(event)
            elif isinstance(event, Drop):
                out.append(event)
    return out, pairer


def test_stereo_frames_do_not_depend_on_arrival_order():
    rng = random.Random(7)
    left, right, joints = stereo_world()
    expected = [Ready(t, {'left': f'left{t}', 'right': f'right{t}'}, f'q{t}')
                for _, t in left]
    for _ in range(300):
        # each stream in its own order (one publisher per topic), interleaved at random
        out, pairer = run_stereo(interleave(rng, left, right, joints))
        assert out == expected and len(pairer) == 0


def test_stereo_frame_alone_in_any_order():
    joints = [('joints', 33 * MS), ('joints', 34 * MS), ('joints', 35 * MS)]
    for order in itertools.permutations([('left', 34 * MS), ('right', 34 * MS), *joints]):
        if [e for e in order if e[0] == 'joints'] != joints:
            continue  # /joint_states come in stamp order (one publisher, reliable)
        out, _ = run_stereo(order)
        assert out == [Ready(34 * MS, {'left': f'left{34 * MS}', 'right': f'right{34 * MS}'},
                             f'q{34 * MS}')]


def test_a_stereo_frame_says_what_it_waits_for_and_times_out_naming_it():
    pairer = StereoPairer(stale_timeout_ns=100 * MS, history_ns=2000 * MS)
    pairer.offer_image('left', 0, 'l0')
    assert list(pairer.poll('no /stereo/pose yet')) == [
        Wait(0, ['right image', 'joint state', 'no /stereo/pose yet'])]
    pairer.offer_joints(0, 'q0')
    pairer.offer_image('right', 0, 'r0')
    assert list(pairer.poll('no /stereo/pose yet')) == [Wait(0, ['no /stereo/pose yet'])]
    pairer.offer_joints(101 * MS, 'q101')
    assert list(pairer.poll('no /stereo/pose yet')) == [
        Drop(0, 'timed out', 'frame at 0.000000000 s waited for no /stereo/pose yet')]
    assert len(pairer) == 0


def test_stereo_drops_a_frame_that_can_never_be_complete():
    out, _ = run_stereo([('left', 0), ('right', 34 * MS), ('joints', 0), ('left', 34 * MS),
                         ('joints', 34 * MS), ('left', 67 * MS), ('right', 67 * MS),
                         ('bad joints', 67 * MS)])
    # (a gap wider than the measured rate allows: ibvs_common's test_sync)
    assert out == [
        Drop(0, 'left/right stamp mismatch', 'left image at 0.000000000 s has no right image'),
        Ready(34 * MS, {'left': f'left{34 * MS}', 'right': f'right{34 * MS}'}, f'q{34 * MS}'),
        Drop(67 * MS, 'no joint state', 'joint state of the image rejected (NaN)')]


def test_stereo_rejects_late_and_stale_images():
    out, _ = run_stereo([('left', 0), ('right', 0), ('joints', 0), ('right', 0),
                         ('right', 67 * MS), ('right', 700 * MS), ('left', 67 * MS)],
                        stale_timeout_ns=500 * MS)
    assert out == [
        Ready(0, {'left': 'left0', 'right': 'right0'}, 'q0'),
        ('rejected', 'right', 0, 'out of order'),
        Drop(67 * MS, 'timed out', 'frame at 0.067000000 s waited for left image, '
             'joint state'),
        ('rejected', 'left', 67 * MS, 'stale')]
    pairer = StereoPairer(stale_timeout_ns=MS, history_ns=MS)
    assert pairer.offer_image('left', 0, 'x', Rejection('bad encoding', 'bgr16')) == \
        Rejection('bad encoding', 'bgr16')
    assert pairer.offer_image('right', 0, 'y') is None  # its pair is dropped silently
    assert list(pairer.poll()) == [] and len(pairer) == 0


def test_stereo_memory_stays_bounded_under_a_flood():
    pairer = StereoPairer(stale_timeout_ns=50 * MS, history_ns=100 * MS)
    for k in range(3000):  # left images only: each frame waits, then times out
        pairer.offer_image('left', k * MS, k)
        pairer.offer_joints(k * MS, k)
        events = list(pairer.poll())
        assert len(pairer) <= 51
        assert all(isinstance(e, Wait) or e.reason == 'timed out' for e in events)
    assert pairer.joints_at(2999 * MS) == (2999, None)
    assert pairer.joints_at(2899 * MS) == (2899, None)
    # older ones are forgotten (joint_history_s): nothing is left to interpolate from
    assert pairer.joints_at(2898 * MS) == (
        None, f'no joint state at or before the image stamp {2898 * MS} ns (the first kept '
        f'is {2899 * MS} ns): nothing to interpolate from')
