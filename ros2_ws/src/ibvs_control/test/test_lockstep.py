"""
The lockstep rules of the joint controller and of the adaptive feedback, without rclpy.

:mod:`ibvs_control.feedback_lockstep` and :mod:`ibvs_control.frame_lockstep` by property:
order of arrival does not change the answers, memory stays bounded under a flood, a missing
input is named, and stale or duplicate inputs are rejected with a reason. Plain functions
without fixtures, so that the first test can run them all in a process where rclpy is
never imported.
"""

import itertools
import random

from ibvs_common.sync import Rejection
from ibvs_common.timing import feedback_frame_ns, frame_stamp_ns
from ibvs_control.feedback_lockstep import FeedbackLockstep
from ibvs_control.frame_lockstep import FrameLockstep
from ibvs_testing.plain import interleave, run_without_rclpy

MS = 1_000_000
DT = MS                 # 1 kHz physics
CAM = 33_333_333        # 30 Hz camera: frames stamped 0, 34, 67, 100 ms, ...


def test_lockstep_tests_run_without_rclpy():
    """The rules and these tests load and pass with no rclpy imported."""
    assert run_without_rclpy(__file__, 'test_lockstep_tests_run_without_rclpy') > 0


# -- FeedbackLockstep (joint controller, model-only loop) -----------------------------------

def expected_feedback(t_ns, lost, latency_ns, initial='zero'):
    """Return the rule in words: the newest frame acting at t not lost, else initial."""
    value = initial
    for n in itertools.count():
        stamp = frame_stamp_ns(n, CAM, DT)
        if stamp + latency_ns > t_ns:
            return value
        if stamp not in lost:
            value = f'fb{stamp}'


def feed(lockstep, events, offers):
    """
    Feed ``events`` (kind, stamp) to ``lockstep`` through ``offers[kind](t_ns)``.

    Return (answers popped after each event, rejections as (kind, stamp, reason), lockstep).
    """
    answers, rejections = [], []
    for kind, t_ns in events:
        rejection = offers[kind](t_ns)
        if rejection is not None:
            rejections.append((kind, t_ns, rejection.reason))
        while (ready := lockstep.pop_ready()) is not None:
            answers.append(ready)
    return answers, rejections, lockstep


def run_feedback(events, latency_ns=0):
    """Feed ``events`` (kind, stamp) into a lockstep; return its answers and rejections."""
    lockstep = FeedbackLockstep(CAM, latency_ns, DT, initial='zero')
    return feed(lockstep, events, {
        'state': lambda t: lockstep.offer_state(t, f'q{t}'),
        'feedback': lambda t: lockstep.offer_feedback(t, f'fb{t}'),
        'lost': lockstep.offer_lost})


def feedback_world(steps, lost, latency_ns=0):
    states = [('state', k * DT) for k in range(steps)]
    frames = [frame_stamp_ns(n, CAM, DT) for n in range(steps * DT // CAM + 1)]
    frames = [('lost' if t in lost else 'feedback', t) for t in frames if t < steps * DT]
    return states, frames


def test_feedback_answers_do_not_depend_on_arrival_order():
    rng = random.Random(12)
    for latency_ns in (0, 20 * MS, 50 * MS):
        lost = {frame_stamp_ns(2, CAM, DT), frame_stamp_ns(3, CAM, DT)}
        states, frames = feedback_world(150, lost, latency_ns)
        expected = [(t, f'q{t}', expected_feedback(t, lost, latency_ns)) for _, t in states]
        for _ in range(40):
            shuffled = frames[:]
            rng.shuffle(shuffled)  # frames in any order, states in stamp order
            answers, rejections, lockstep = run_feedback(interleave(rng, states, shuffled),
                                                         latency_ns)
            assert rejections == [] and answers == expected
            assert not lockstep.states and lockstep.waiting_for() == []


def test_feedback_answers_for_every_interleaving_of_a_short_run():
    states, frames = feedback_world(70, lost={34 * MS})
    states = [s for s in states if s[1] in (0, MS, 34 * MS, 35 * MS, 67 * MS)]
    expected = None
    for order in itertools.permutations(states + frames):
        if [e for e in order if e[0] == 'state'] != states:
            continue  # /joint_states come in stamp order (one publisher, reliable)
        answers, rejections, _ = run_feedback(order)
        assert rejections == []
        expected = expected or answers
        assert answers == expected
    assert [a[2] for a in expected] == ['fb0', 'fb0', 'fb0', 'fb0', f'fb{67 * MS}']


def test_a_state_waits_for_its_frame_and_says_which():
    lockstep = FeedbackLockstep(CAM, 0, DT, feedback_name='/ibvs/q_feedback',
                                lost_name='/stereo/frame_lost')
    assert lockstep.offer_state(34 * MS, 'q') is None
    assert lockstep.pop_ready() is None
    assert lockstep.waiting_for() == [
        f'/ibvs/q_feedback of frame {34 * MS} ns (or its /stereo/frame_lost)']
    assert lockstep.waiting_for(0) == ['/ibvs/q_feedback of frame 0 ns (or its '
                                       '/stereo/frame_lost)']
    assert FeedbackLockstep(CAM, 20 * MS, DT).waiting_for(19 * MS) == []  # none acts yet
    lockstep.offer_lost(34 * MS)
    assert lockstep.waiting_for() == [] and lockstep.pop_ready() == (34 * MS, 'q', None)


def test_feedback_rejects_stale_duplicate_and_contradicting_inputs():
    lockstep = FeedbackLockstep(CAM, 0, DT)
    assert lockstep.offer_feedback(0, 'fb0') is None
    assert lockstep.offer_feedback(0, 'again') == Rejection('duplicate stamp', '0 ns')
    assert lockstep.offer_lost(0) == Rejection('frame has a q_feedback', '0 ns')
    assert lockstep.offer_lost(34 * MS) is None
    assert lockstep.offer_lost(34 * MS) == Rejection('duplicate stamp', f'{34 * MS} ns')
    assert lockstep.offer_feedback(34 * MS, 'x') == Rejection('frame was lost', f'{34 * MS} ns')
    lockstep.offer_state(0, 'q0')
    lockstep.offer_state(67 * MS, 'q67')
    assert lockstep.offer_state(67 * MS, 'q').reason == 'stale stamp'
    assert lockstep.pop_ready() == (0, 'q0', 'fb0')
    assert lockstep.offer_state(68 * MS, 'q') is None
    assert lockstep.offer_feedback(67 * MS, 'fb67') is None
    assert [lockstep.pop_ready()[0] for _ in range(2)] == [67 * MS, 68 * MS]
    # frame 0 and the lost frame 1 are no longer needed once frame 2 acts
    assert lockstep.offer_feedback(0, 'late') == Rejection('stale stamp',
                                                           '0 ns is no longer needed')
    assert lockstep.offer_lost(34 * MS).reason == 'stale stamp'
    assert list(lockstep.feedback) == [67 * MS] and not lockstep.lost


def test_feedback_memory_stays_bounded_under_a_flood():
    lockstep = FeedbackLockstep(CAM, 0, DT, max_buffer=100)
    reasons = set()
    for k in range(1, 2000):  # frame 0 never comes: nothing can be answered
        for rejection in (lockstep.offer_state(k * DT, k),
                          lockstep.offer_feedback(frame_stamp_ns(k, CAM, DT), k),
                          lockstep.offer_lost(frame_stamp_ns(k, CAM, DT) + 1)):
            reasons.add(rejection and rejection.reason)
        assert max(len(lockstep.states), len(lockstep.feedback), len(lockstep.lost)) <= 100
        assert lockstep.pop_ready() is None
    assert reasons == {None, 'buffer full'}
    assert lockstep.waiting_for() == ['q_feedback of frame 0 ns (or its frame_lost)']


def test_feedback_frame_rule_is_the_timing_rule():
    """pop_ready uses timing.feedback_frame_ns, the rule the simulator stamps by."""
    lockstep = FeedbackLockstep(CAM, 13 * MS, DT, initial='zero')
    for n in range(4):
        lockstep.offer_feedback(frame_stamp_ns(n, CAM, DT), n)
    for k in range(120):
        lockstep.offer_state(k * DT, None)
        frame = feedback_frame_ns(k * DT, CAM, 13 * MS, DT)
        want = 'zero' if frame is None else [frame_stamp_ns(n, CAM, DT)
                                             for n in range(4)].index(frame)
        assert lockstep.pop_ready() == (k * DT, None, want)


# -- FrameLockstep (adaptive feedback) -------------------------------------------------------

def frame_world(frames=4):
    stamps = [frame_stamp_ns(n, CAM, DT) for n in range(frames)]
    joints = [('joints', t) for t in sorted({0, 33 * MS, *stamps, stamps[-1] + DT})]
    return ([('frame', t) for t in stamps], joints,
            [('status', t) for t in stamps])


def measured(t_ns):
    return t_ns // MS % 2 == 0  # frames at 0, 34 and 100 ms measured, 67 ms not


def run_frames(events, needs_status):
    lockstep = FrameLockstep(needs_status=needs_status)
    return feed(lockstep, events, {
        'frame': lambda t: lockstep.offer_frame(t, f'p{t}'),
        'joints': lambda t: lockstep.offer_joints(t, f'q{t}'),
        'status': lambda t: lockstep.offer_status(t, measured(t))})


def test_frame_answers_do_not_depend_on_arrival_order():
    rng = random.Random(4)
    frames, joints, statuses = frame_world()
    for needs_status in (False, True):
        expected = [(t, f'p{t}', f'q{t}', measured(t) if needs_status else True)
                    for _, t in frames]
        for _ in range(200):
            shuffled = statuses[:]
            rng.shuffle(shuffled)  # statuses in any order, frames and joints in order
            streams = (frames, joints, shuffled) if needs_status else (frames, joints)
            answers, rejections, lockstep = run_frames(interleave(rng, *streams), needs_status)
            assert rejections == [] and answers == expected
            assert lockstep.waiting_for() == []


def test_a_frame_waits_for_its_joint_state_and_status_and_says_which():
    lockstep = FrameLockstep(needs_status=True, joints_name='/joint_states',
                             status_name='/ibvs/feature_status')
    assert lockstep.waiting_for() == []
    lockstep.offer_joints(33 * MS, 33.0)
    lockstep.offer_frame(34 * MS, 'p')
    assert lockstep.pop_ready() is None
    assert lockstep.waiting_for() == [f'/joint_states at or after {34 * MS} ns',
                                      f'/ibvs/feature_status of frame {34 * MS} ns']
    lockstep.offer_joints(35 * MS, 35.0)  # off the frame's stamp: interpolated
    lockstep.offer_status(34 * MS, False)
    assert lockstep.pop_ready() == (34 * MS, 'p', 34.0, False)
    # a status for a frame already answered is dropped without a word
    assert lockstep.offer_status(34 * MS, True) is None and lockstep.waiting_for() == []


def test_a_frame_without_a_joint_state_is_answered_with_the_reason():
    lockstep = FrameLockstep()
    lockstep.offer_frame(10 * MS, 'p')   # before the first joint state: never
    lockstep.offer_joints(12 * MS, 12.0)
    t_ns, item, joints, measured = lockstep.pop_ready()
    assert (t_ns, item, measured) == (10 * MS, 'p', True)
    assert joints.reason == 'no joint state' and 'nothing to interpolate from' in joints.detail


def test_frames_reject_stale_inputs_and_stay_bounded():
    lockstep = FrameLockstep(history=50, needs_status=True, full_note='waiting for the camera')
    assert lockstep.offer_joints(10, 'a') is None
    assert lockstep.offer_joints(10, 'b').reason == 'stale stamp'
    assert lockstep.offer_frame(5, 'p') is None
    assert lockstep.offer_frame(5, 'p') == Rejection('stale stamp', '5 ns, not after 5 ns')
    reasons = set()
    for k in range(1, 500):  # no status ever comes: frames pile up
        for rejection in (lockstep.offer_joints(10 + k, k), lockstep.offer_frame(5 + k, k),
                          lockstep.offer_status(10_000 + k, True)):
            reasons.add(rejection and rejection.reason)
        assert len(lockstep.joints) <= 50 and len(lockstep.frames) <= 50
    assert reasons == {None, 'buffer full'}
    assert lockstep.offer_frame(9999, 'p') == Rejection(
        'buffer full', '9999 ns dropped: waiting for the camera')


def test_the_feedback_lockstep_takes_a_new_time_line_after_forget():
    # the clock jumped back (a restarted simulator): frames and joint states stamped before
    # the old newest are answered, not refused as stale
    lockstep = FrameLockstep(100)
    for t in (10_000_000, 20_000_000):
        assert lockstep.offer_joints(t, ('q', t)) is None
        assert lockstep.offer_frame(t, 'frame') is None
        assert lockstep.pop_ready()[0] == t
    assert lockstep.offer_frame(1_000_000, 'frame') is not None  # the old time line
    lockstep.forget()
    assert lockstep.offer_joints(1_000_000, ('q', 1)) is None
    assert lockstep.offer_frame(1_000_000, 'frame') is None
    assert lockstep.pop_ready()[:3] == (1_000_000, 'frame', ('q', 1))


def test_a_frame_waits_for_the_joint_state_of_its_action_time():
    # with latency and the encoders' prediction: the frame at 0 acts from 100 ms and is
    # answered once a state stamped then has come; the newest state is the one predicted to
    lockstep = FrameLockstep(100, action_ns=lambda t: t + 100_000_000)
    assert lockstep.offer_joints(0, 'q0') is None
    assert lockstep.offer_frame(0, 'frame') is None
    assert lockstep.pop_ready() is None
    assert 'at or after 100000000 ns' in lockstep.waiting_for()[0]
    assert lockstep.offer_joints(100_000_000, 'q100') is None
    assert lockstep.pop_ready()[:3] == (0, 'frame', 'q0')
    assert lockstep.action_joints() == (100_000_000, 'q100')
