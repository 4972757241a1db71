"""
sensor_msgs/JointState <-> (6,) arrays by joint name, and the range a joint value is read in.

:func:`read_joints` maps the values by name (:func:`joint_order`) and refuses, with an
:class:`.input_error.InputError`, a message it cannot map or whose values are non-finite or
outside a bound (:func:`position_bounds`, :func:`velocity_bounds`, :func:`travel_bounds`).
"""

from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING

from builtin_interfaces.msg import Time
from ibvs_model import IRB4600
import numpy as np
from numpy.typing import ArrayLike, NDArray
from sensor_msgs.msg import JointState

from . import contract
from .input_error import InputError
from .msg_time import ns_stamp

if TYPE_CHECKING:
    from ibvs_model.robot import RobotParams


#: How far (rad) a start posture may lie outside its joint's travel (ibvs_model.IRB4600
#: q_min, q_max) and still be read (:func:`travel_bounds`).
POSITION_MARGIN_RAD = 0.1
#: Largest |position| (rad) of a joint state or trajectory point that is read
#: (:func:`position_bounds`). Not the travel: the paper's feedforward leads the arm and
#: overshoots it (scenarios 1-3: up to 44 rad on joint 1 in the first steps), and the ideal
#: actuators follow where no hard stop is modelled; a thousand radians is no reading.
POSITION_BOUND_RAD = 1000.0
#: Largest |velocity| (rad/s) of a joint that is read: about ten times the 1.2e3 rad/s the
#: paper's feedforward asks of the ideal actuators (a stand-in plant without PyBullet's
#: 100 rad/s cap follows it), far below what breaks the dynamics.
SPEED_BOUND_RAD_S = 1e4


def joint_state(stamp: int | Time, position: ArrayLike | None = None,
                velocity: ArrayLike | None = None, effort: ArrayLike | None = None,
                names: Iterable[str] = contract.JOINT_NAMES) -> JointState:
    """Build a JointState with the contract's joint names."""
    msg = JointState()
    msg.header.stamp = stamp if isinstance(stamp, Time) else ns_stamp(stamp)
    msg.header.frame_id = contract.BASE_FRAME
    msg.name = list(names)
    if position is not None:
        msg.position = [float(v) for v in position]
    if velocity is not None:
        msg.velocity = [float(v) for v in velocity]
    if effort is not None:
        msg.effort = [float(v) for v in effort]
    return msg


#: Most distinct (JointState.name, names) pairs whose mapping :func:`joint_order` keeps: a
#: cell publishes one or two name lists; a publisher of ever new names (a fuzzer) does not
#: grow the cache beyond this.
JOINT_ORDER_CACHE = 64
_JOINT_ORDERS: dict = {}


def joint_order(given: Sequence[str], names: Sequence[str] = contract.JOINT_NAMES
                ) -> tuple[NDArray[np.int_] | None, tuple[str, ...]]:
    """
    Return (where each of ``names`` is in ``given``, the names of ``given`` that are ignored).

    joint_state_broadcaster publishes every joint of every hardware of the
    controller_manager (an arm's track, a gripper), in its own order. The arm's joints
    ``names`` are taken by name, in any order; the others are ignored and returned (in the
    order given) so that a node can say once which it ignores. The index array is None
    when ``given`` is ``names`` as it is (no reordering needed). Raises
    :class:`InputError`: 'no joint names' (``given`` empty: values are mapped by name),
    'wrong joint names' (a name given twice) or 'missing joints' (one of ``names`` not
    given).
    """
    key = (tuple(given), tuple(names))
    found = _JOINT_ORDERS.get(key)
    if found is not None:
        return found
    given, names = key
    if not given:
        raise InputError('no joint names', 'JointState.name is empty; values are mapped by name')
    if len(set(given)) != len(given):
        raise InputError('wrong joint names', f'{list(given)}: a name given twice')
    missing = [n for n in names if n not in given]
    if missing:
        raise InputError('missing joints', f'{missing} not in {list(given)}')
    order = None if given == names else np.array([given.index(n) for n in names])
    found = (order, tuple(n for n in given if n not in names))
    if len(_JOINT_ORDERS) >= JOINT_ORDER_CACHE:
        _JOINT_ORDERS.clear()
    _JOINT_ORDERS[key] = found
    return found


def ignored_joints(msg: JointState, names: Sequence[str] = contract.JOINT_NAMES
                   ) -> tuple[str, ...]:
    """Return the joints of ``msg`` that are not ``names`` (ignored); () if it cannot be read."""
    try:
        return joint_order(msg.name, names)[1]
    except InputError:
        return ()


#: The per-joint fields of a JointState.
JOINT_FIELDS = ('position', 'velocity', 'effort')


def read_joints(msg: JointState, field: str = 'position',
                names: Sequence[str] = contract.JOINT_NAMES,
                bound: tuple[ArrayLike, ArrayLike] | None = None) -> NDArray[np.float64]:
    """
    Return ``msg.<field>`` of the joints ``names``, a (6,) array in their order.

    Values are mapped by joint name (:func:`joint_order`): the message must name each of
    ``names`` once, in any order, and may name other joints too (a track, a gripper: what
    joint_state_broadcaster publishes), whose values are ignored, not checked. Raises
    :class:`InputError` for the names :func:`joint_order` refuses, a field whose length is
    not the number of names given, a non-finite value of one of ``names`` (in ``field``, or
    in another of :data:`JOINT_FIELDS`, which may be empty: a NaN there is a broken
    publisher, and the whole message is refused rather than half used) or, with
    ``bound`` = (low, high) (arrays in the order of ``names``), a value outside [low, high]
    ('out of range': :func:`position_bounds`, :func:`velocity_bounds`).
    """
    order, _ = joint_order(msg.name, names)
    values = np.asarray(getattr(msg, field), dtype=float)
    if values.shape != (len(msg.name),):
        raise InputError(f'wrong {field} length',
                         f'{values.size} values for {len(msg.name)} joint names')
    if order is not None:
        values = values[order]
    if not np.isfinite(values).all():
        raise InputError(f'non-finite {field}', f'{values.tolist()}')
    for other in JOINT_FIELDS:
        if other == field:
            continue
        extra = np.asarray(getattr(msg, other), dtype=float)
        if extra.shape == (len(msg.name),) and order is not None:
            extra = extra[order]
        if not np.isfinite(extra).all():
            raise InputError(f'non-finite {other}', f'{extra.tolist()}')
    if bound is not None and not ((values >= bound[0]) & (values <= bound[1])).all():
        raise InputError(f'{field} out of range',
                         f'{values.tolist()}, allowed {np.round(bound[0], 3).tolist()} to '
                         f'{np.round(bound[1], 3).tolist()}')
    return values


def travel_bounds(params: 'RobotParams' = IRB4600
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return (low, high) of a posture the arm can start from: the travel, with a margin."""
    return (np.asarray(params.q_min, dtype=float) - POSITION_MARGIN_RAD,
            np.asarray(params.q_max, dtype=float) + POSITION_MARGIN_RAD)


def _symmetric_bounds(limit):
    """Return read-only (low, high) arrays of +-``limit`` for the six joints."""
    high = np.full(len(contract.JOINT_NAMES), float(limit))
    low = -high
    low.flags.writeable = high.flags.writeable = False
    return low, high


# Built once: the joint controller reads both bounds on every /joint_states (1 kHz).
_POSITION_BOUNDS = _symmetric_bounds(POSITION_BOUND_RAD)
_VELOCITY_BOUNDS = _symmetric_bounds(SPEED_BOUND_RAD_S)


def position_bounds() -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return (low, high) of a joint position that is read: +-POSITION_BOUND_RAD."""
    return _POSITION_BOUNDS


def velocity_bounds() -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return (low, high) of a joint velocity that can be meant: +-SPEED_BOUND_RAD_S."""
    return _VELOCITY_BOUNDS


def check_finite(msg: JointState, fields: Iterable[str]) -> None:
    """
    Raise :class:`InputError` if a JointState field in ``fields`` holds a non-finite value.

    For the fields a consumer does not read (e.g. velocity and effort of a position
    reference): they may be empty, but a NaN or inf there means a broken publisher, and the
    whole message is rejected rather than half used.
    """
    for field in fields:
        values = np.asarray(getattr(msg, field), dtype=float)
        if not np.all(np.isfinite(values)):
            raise InputError(f'non-finite {field}', f'{values.tolist()}')
