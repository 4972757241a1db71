"""
The sim-time rules of docs/design.md §4, in integer nanoseconds; plain Python, no rclpy.

Kept free of ROS so that the model-only closed loop (ibvs_control.closed_loop) and the
simulator's core (ibvs_sim.simulator) use the very rule the nodes use.
"""


def period_ns(rate_hz):
    """Return the period of ``rate_hz`` in integer nanoseconds (rounded)."""
    return int(round(1e9 / float(rate_hz)))


def feedback_frame_ns(t_ns, camera_period_ns, latency_ns):
    """
    Return the stamp (ns) of the camera frame whose q_feedback applies at sim time ``t_ns``.

    Camera frames are taken at n * camera_period_ns (n = 0, 1, ...). The feedback computed
    from frame n takes effect ``latency_ns`` after it (camera-to-command latency, a
    parameter in sim time, docs/design.md §4) and holds until the next one does. Returns
    None before the first frame takes effect. The joint controller waits for exactly this
    q_feedback before it answers /joint_states at ``t_ns``, which makes runs deterministic.
    """
    if camera_period_ns <= 0 or latency_ns < 0:
        raise ValueError('camera_period_ns must be > 0 and latency_ns >= 0')
    if t_ns < latency_ns:
        return None
    return ((t_ns - latency_ns) // camera_period_ns) * camera_period_ns
