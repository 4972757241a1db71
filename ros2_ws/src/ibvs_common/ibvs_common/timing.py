"""
The sim-time rules of docs/design.md §4, in integer nanoseconds; plain Python, no rclpy.

Kept free of ROS so that the model-only closed loop (ibvs_control.closed_loop) and the
simulator's core (ibvs_sim.simulator) use the very rule the nodes use. Times are integer
nanoseconds; a duration given in seconds (a parameter) becomes nanoseconds through
:func:`seconds_to_ns` and a time goes back to seconds through :func:`ns_to_seconds`, the
one rule for each.
"""

from typing import Optional

#: Nanoseconds in a second: builtin_interfaces/Time.nanosec must be below this.
NS_PER_S = 1_000_000_000


def seconds_to_ns(seconds: float) -> int:
    """
    Return a duration in seconds as integer nanoseconds, rounded to the nearest.

    ``int(round(float(seconds) * 1e9))``: the product is a double, rounded half to even; a
    parameter such as 0.5 s becomes exactly 500_000_000 ns.
    """
    return int(round(float(seconds) * 1e9))


def ns_to_seconds(t_ns: int) -> float:
    """Return integer nanoseconds as seconds (``t_ns * 1e-9``, a double)."""
    return t_ns * 1e-9


#: How far (ns) a node's clock may lag the stamps it reads, beyond one input period: the
#: period of a lockstep graph's /clock (``clock_rate_hz``, 10 Hz) or a real cell's clock
#: offset between hosts. A stamp that leads by more is refused ('stamp in the future') and
#: moves no order: taken, it would refuse every later input stamped before it.
STAMP_LEAD_MARGIN_NS = 100_000_000


def stamp_lead_ns(stale_timeout_s: float, input_period_ns: int) -> int:
    """
    Return how far (ns) an input's stamp may lead the newest time its node knows.

    One period of the input (the next input of a stream is one period after the last) and
    the clock's lag, :data:`STAMP_LEAD_MARGIN_NS`, or ``stale_timeout_s`` (the parameter
    that ages inputs out) where that is shorter: the ``lead_ns`` of :func:`read_stamp`.
    """
    return min(seconds_to_ns(stale_timeout_s), STAMP_LEAD_MARGIN_NS) + int(input_period_ns)


def period_ns(rate_hz: float) -> int:
    """Return the period of ``rate_hz`` in integer nanoseconds (rounded)."""
    return int(round(1e9 / float(rate_hz)))


def check_camera_rate(camera_rate_hz: float, physics_rate_hz: float) -> None:
    """
    Raise ValueError unless frames come no faster than physics steps (the one rate rule).

    A frame is rendered at a physics step (:func:`frame_stamp_ns`), so T_cam must be at
    least one step; it need not be a whole number of steps.
    """
    if period_ns(camera_rate_hz) < period_ns(physics_rate_hz):
        raise ValueError(f'{camera_rate_hz} Hz exceeds physics_rate_hz = {physics_rate_hz} Hz: '
                         'frames are taken at physics steps; allowed: camera_rate_hz <= '
                         'physics_rate_hz')


def frame_stamp_ns(n: int, camera_period_ns: int, step_ns: int) -> int:
    """
    Return the stamp (ns) of camera frame ``n``: the sim time of the step it is rendered from.

    Frame n is due at n * camera_period_ns and rendered from the first physics step at or
    after that time (the camera period need not be a whole number of steps: 30 Hz frames on
    1 kHz physics are stamped 0, 34, 67, 100 ms, ...).
    """
    return -(-n * camera_period_ns // step_ns) * step_ns


def is_frame_stamp(t_ns: int, camera_period_ns: int, step_ns: int) -> bool:
    """
    Return whether ``t_ns`` is the stamp of a camera frame (:func:`frame_stamp_ns`).

    Frame n is stamped in [n T, n T + dt) and T >= dt, so the only candidate is n = t // T.
    """
    n = t_ns // camera_period_ns
    return t_ns >= 0 and frame_stamp_ns(n, camera_period_ns, step_ns) == t_ns


def feedback_action_ns(stamp_ns: int, latency_ns: int, step_ns: int) -> int:
    """
    Return the sim time (ns) from which the q_feedback of the frame stamped ``stamp_ns`` acts.

    The first physics step at or after stamp + latency: the inverse of
    :func:`feedback_frame_ns` (the frame it names at that step is this one, and at the step
    before an earlier one). With no latency it is the frame's own stamp. The feedback node
    predicts the frame's features to this time (ibvs_control.prediction).
    """
    if latency_ns < 0 or step_ns <= 0:
        raise ValueError('step_ns must be > 0 and latency_ns >= 0')
    return -(-(stamp_ns + latency_ns) // step_ns) * step_ns


def feedback_frame_ns(t_ns: int, camera_period_ns: int, latency_ns: int,
                      step_ns: int) -> Optional[int]:
    """
    Return the stamp (ns) of the camera frame whose q_feedback applies at sim time ``t_ns``.

    Frames are stamped :func:`frame_stamp_ns` (on the physics grid of ``step_ns``). The
    feedback computed from a frame takes effect ``latency_ns`` after its stamp
    (camera-to-command latency, a parameter in sim time, docs/design.md §4) and holds until
    the next one does. Returns None before the first frame takes effect. The joint
    controller waits for exactly this q_feedback before it answers /joint_states at
    ``t_ns``, which makes runs deterministic.
    """
    if camera_period_ns <= 0 or latency_ns < 0 or step_ns <= 0:
        raise ValueError('camera_period_ns and step_ns must be > 0 and latency_ns >= 0')
    if t_ns < latency_ns:
        return None
    # The newest frame n whose stamp is at most t - latency: stamps are on the step grid,
    # so ceil(n T / dt) dt <= x  <=>  n T <= floor(x / dt) dt.
    n = (t_ns - latency_ns) // step_ns * step_ns // camera_period_ns
    return frame_stamp_ns(n, camera_period_ns, step_ns)
