"""
The decoupled outer loop (eq. 33-41) around C1 T_inner at random configurations.

Acceptance: closed around its linearised plant C1 T_inner(s), the sampled controller
C1^+ k_d reproduces eq. (36) (zeta = 1/sqrt(2), omega_n = 10 rad/s) within 2 % of the
step on the 5 observable channels, for C1 at 20 random configurations.
"""

from ibvs_control import youla
from ibvs_control.decoupling import decouple
from ibvs_control.filters import StateSpaceFilter
from ibvs_model import default_model, IRB4600
import numpy as np
import pytest

TAU = 0.01
WN = 10.0
ZETA = 1.0 / np.sqrt(2.0)
CAMERA_DT = 1.0 / 30.0
SUBSTEPS = 20
DURATION = 1.5


def random_configurations(count, seed=5):
    """Joint angles within the limits with both markers in front of the camera."""
    model = default_model()
    rng = np.random.default_rng(seed)
    lo, hi = np.array(IRB4600.q_min), np.array(IRB4600.q_max)
    out = []
    while len(out) < count:
        q = rng.uniform(np.maximum(lo, -np.pi), np.minimum(hi, np.pi))
        if np.all(model.camera.to_camera(model.markers(q))[:, 2] > 0.3):
            out.append(q)
    return model, out


def inner_plant_ss(dt):
    """Exact ZOH discretisation of eq. (29) as (A, B, C) of one joint."""
    a, b, c, _ = youla.inner_closed_loop(TAU).discretise(dt, 'zoh').to_ss()
    return a, b.reshape(-1), c.reshape(-1)


def run_outer(c1, references, svd_rcond=1e-6, svd_damping=0.0):
    """
    Run the sampled outer loop around C1 T_inner(s) for several reference steps at once.

    ``references`` (6, m): one image-space step per column. T_inner is simulated exactly
    (zero-order hold of q_feedback between frames), with SUBSTEPS outputs per frame.
    Returns (t, y (len(t), 6, m)).
    """
    dec = decouple(c1, svd_rcond, svd_damping)
    m = references.shape[1]
    k = StateSpaceFilter(youla.outer_controller_discrete(TAU, WN, ZETA, CAMERA_DT), 6 * m)
    a, b, c = inner_plant_ss(CAMERA_DT / SUBSTEPS)
    x = np.zeros((a.shape[0], 6 * m))
    frames = int(round(DURATION / CAMERA_DT))
    ts, ys = [], []
    for n in range(frames):
        q = (c @ x).reshape(6, m)
        error = references - c1 @ q
        q_fb = k.step((dec.pinv @ error).reshape(-1))
        for s in range(SUBSTEPS):
            ts.append((n + s / SUBSTEPS) * CAMERA_DT)
            ys.append(c1 @ (c @ x).reshape(6, m))
            x = a @ x + np.outer(b, q_fb)
    return np.array(ts), np.array(ys), dec


@pytest.fixture(scope='module')
def configurations():
    return random_configurations(20)


def test_c1_has_rank_five_with_e6_unobservable(configurations):
    model, qs = configurations
    for q in qs:
        dec = decouple(model.jacobian(q))
        assert dec.rank == 5
        assert dec.s[5] < 1e-9 * dec.s[0]
        assert abs(dec.Vt[5, 5]) == pytest.approx(1.0, abs=1e-9)
        np.testing.assert_allclose(dec.pinv[5], 0.0, atol=1e-12)


def test_truncated_inverse_is_a_pseudo_inverse(configurations):
    model, qs = configurations
    c1 = model.jacobian(qs[0])
    dec = decouple(c1)
    np.testing.assert_allclose(c1 @ dec.pinv @ c1, c1, atol=1e-9 * np.abs(c1).max())
    np.testing.assert_allclose(dec.pinv @ c1 @ dec.pinv, dec.pinv,
                               atol=1e-9 * np.abs(dec.pinv).max())
    # channel by channel (what the trust region clips) the inverse is the same matrix
    error = np.linspace(-3.0, 5.0, 6)
    np.testing.assert_allclose(dec.joints(dec.channels(error)), dec.pinv @ error,
                               atol=1e-12 * np.abs(dec.pinv @ error).max())
    assert dec.gain_inv[5] == 0.0
    damped = decouple(c1, svd_damping=0.5)
    # svd_damping shrinks every inverted gain: sigma / (sigma^2 + lambda^2) < 1 / sigma
    assert np.linalg.norm(damped.pinv, 2) < np.linalg.norm(dec.pinv, 2)
    assert damped.rank == dec.rank and dec.condition == pytest.approx(dec.s[0] / dec.s[4])


def eq36_deviation(c1, run):
    """
    Return the largest deviation from eq. (36) of C1's five observable channels, in steps.

    ``run(c1, references)`` returns (frame times, y at the frames) for a unit image-space
    step along each u_i, i < 5: each channel's response along its own u_i is held against
    the Butterworth step, and along the others (coupling) against 0.
    """
    u = decouple(c1).U
    t, y = run(c1, u[:, :5])
    reference = youla.butterworth(WN, ZETA).step(t)
    channels = np.einsum('ji,tjk->tik', u, y)
    return max(max(np.max(np.abs(channels[:, i, i] - reference)),
                   np.max(np.abs(np.delete(channels[:, :, i], i, axis=1))))
               for i in range(5))


def run_outer_at_frames(c1, references):
    """Return :func:`run_outer`'s (t, y) at the frames, checking that C1 has rank 5."""
    t, y, dec = run_outer(c1, references)
    assert dec.rank == 5
    return t[::SUBSTEPS], y[::SUBSTEPS]


def test_outer_loop_reproduces_eq36_on_observable_channels(configurations):
    model, qs = configurations
    worst = max(eq36_deviation(model.jacobian(q), run_outer_at_frames) for q in qs)
    assert worst < 0.02, f'worst deviation from eq. (36): {worst:.4f} of the step'


def run_deployed(c1, references, dt_ns=1_000_000, camera_ns=33_333_333, steps=1500):
    """
    Run the outer loop as deployed; return (frame times, y at the frames).

    The inner loop is the sampled G_c around 1/s^2 at 1 kHz; frame n is taken at the first
    1 ms tick at or after n * camera_ns, as in the model-only loop.
    """
    dec = decouple(c1)
    m = references.shape[1]
    k = StateSpaceFilter(youla.outer_controller_discrete(TAU, WN, ZETA, camera_ns * 1e-9),
                         6 * m)
    inner = StateSpaceFilter(youla.inner_controller_discrete(TAU, dt_ns * 1e-9), 6 * m)
    dt = dt_ns * 1e-9
    q, qd, q_fb = np.zeros(6 * m), np.zeros(6 * m), np.zeros(6 * m)
    ts, ys, frame = [], [], 0
    for tick in range(steps):
        if frame * camera_ns <= tick * dt_ns:
            ts.append(frame * camera_ns * 1e-9)
            ys.append(c1 @ q.reshape(6, m))
            q_fb = k.step((dec.pinv @ (references - ys[-1])).reshape(-1))
            frame += 1
        v = inner.step(q_fb - q)
        q, qd = q + qd * dt + 0.5 * v * dt * dt, qd + v * dt
    return np.array(ts), np.array(ys)


def test_outer_loop_with_the_sampled_inner_loop_still_reproduces_eq36(configurations):
    model, qs = configurations
    worst = max(eq36_deviation(model.jacobian(q), run_deployed) for q in qs)
    assert worst < 0.02, f'worst deviation from eq. (36): {worst:.4f} of the step'


def test_unobservable_channel_gets_no_feedback(configurations):
    model, qs = configurations
    c1 = model.jacobian(qs[3])
    dec = decouple(c1)
    # an image error along u_6 (no joint can produce it) moves no joint
    _, y, _ = run_outer(c1, dec.U[:, 5:6])
    assert np.max(np.abs(y)) < 1e-9


def test_intersample_response_stays_close_to_eq36(configurations):
    model, qs = configurations
    c1 = model.jacobian(qs[0])
    u = decouple(c1).U
    t, y, _ = run_outer(c1, u[:, :1])
    reference = youla.butterworth(WN, ZETA).step(t)
    along = y[:, :, 0] @ u[:, 0]
    # between frames the held q_feedback and eq. (29) add a ripple (documented: ~6 %)
    assert np.max(np.abs(along - reference)) < 0.08
    assert along[-1] == pytest.approx(1.0, abs=1e-4)


def test_decouple_rejects_bad_input():
    with pytest.raises(ValueError):
        decouple(np.full((6, 6), np.nan))
    with pytest.raises(ValueError):
        decouple(np.eye(6), svd_rcond=0.0)
    assert decouple(np.zeros((6, 6))).rank == 0
