"""
The arm's joint limits as data: the joint_limits YAML of ros2_control and MoveIt (no ROS).

``data/irb4600_60_205_joint_limits.yaml`` (installed also as
``share/ibvs_model/config/irb4600_60_205_joint_limits.yaml``, for a MoveIt config or a
controller's parameters) holds, per joint ``joint_1`` .. ``joint_6`` (abb_ros2's names),
the range, speed, acceleration and jerk limits in the parameter names of ros2_control's
``joint_limits`` (``has_velocity_limits``, ``max_velocity``, ...); where each number comes
from is written in the file. :func:`load` reads such a file and checks it;
:data:`IRB4600_60_205` is this arm's, the one source that :class:`.robot.RobotParams` (the
ranges and speeds of the model, the IK and the model loop) and :mod:`.drive` (the speed,
acceleration and jerk of the joint controller's shaper and the simulated EGM drive) take.
"""

from dataclasses import dataclass
from importlib.resources import files
import math
from pathlib import Path

import yaml

#: The limits file of the IRB 4600-60/2.05, inside this package.
FILE = files(__package__) / 'data' / 'irb4600_60_205_joint_limits.yaml'
#: The arm's joints, in the order of the model's q (abb_ros2's names).
JOINTS = tuple(f'joint_{i}' for i in range(1, 7))
#: Each kind of limit: its has_* flag and the value keys it needs.
KINDS = {'position': ('min_position', 'max_position'), 'velocity': ('max_velocity',),
         'acceleration': ('max_acceleration',), 'jerk': ('max_jerk',)}


@dataclass(frozen=True)
class JointLimits:
    """Per joint of :attr:`joints` (tuples in that order): range, speed, acceleration, jerk."""

    joints: tuple[str, ...]
    min_position: tuple[float, ...]
    max_position: tuple[float, ...]
    max_velocity: tuple[float, ...]
    max_acceleration: tuple[float, ...]
    max_jerk: tuple[float, ...]


def load(path: 'str | Path | None' = None, joints: tuple[str, ...] = JOINTS) -> JointLimits:
    """
    Return the limits of ``joints`` in a joint_limits YAML file (default: :data:`FILE`).

    Parameters
    ----------
    path : str or Path, optional
        The file: a mapping ``joint_limits`` of joint name to its limits, in ros2_control's
        names. Every kind of :data:`KINDS` must be set (``has_<kind>_limits: true``) for
        every joint: the shaper, the drive and the model need all of them.
    joints : tuple of str
        The joints, in the order of the returned tuples.

    Raises
    ------
    ValueError
        Naming the file, the joint and the key: a joint or a limit missing, a limit not a
        finite number, a speed, acceleration or jerk not above 0, or a range whose minimum
        is not below its maximum.

    """
    source = FILE if path is None else Path(path)
    document = yaml.safe_load(source.read_text())
    table = document.get('joint_limits') if isinstance(document, dict) else None
    if not isinstance(table, dict):
        raise ValueError(f'{source}: no joint_limits mapping')
    values = {key: [] for keys in KINDS.values() for key in keys}
    for joint in joints:
        limits = table.get(joint)
        if not isinstance(limits, dict):
            raise ValueError(f'{source}: no joint_limits.{joint}')
        for kind, keys in KINDS.items():
            if limits.get(f'has_{kind}_limits') is not True:
                raise ValueError(f'{source}: joint_limits.{joint}.has_{kind}_limits must be '
                                 'true (the shaper, the drive and the model need it)')
            for key in keys:
                value = limits.get(key)
                if isinstance(value, bool) or not isinstance(value, (int, float)) \
                        or not math.isfinite(value):
                    raise ValueError(f'{source}: joint_limits.{joint}.{key} must be a finite '
                                     f'number, got {value!r}')
                if kind != 'position' and not value > 0.0:
                    raise ValueError(f'{source}: joint_limits.{joint}.{key} must be > 0, '
                                     f'got {value!r}')
                values[key].append(float(value))
        if not values['min_position'][-1] < values['max_position'][-1]:
            raise ValueError(f'{source}: joint_limits.{joint}.min_position must be below its '
                             'max_position')
    return JointLimits(tuple(joints), **{key: tuple(v) for key, v in values.items()})


#: The IRB 4600-60/2.05's limits (:data:`FILE`).
IRB4600_60_205 = load()
