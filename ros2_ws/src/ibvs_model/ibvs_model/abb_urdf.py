"""
ABB's own link frames of the IRB 4600-60/2.05, as robot_state_publisher computes them.

The cell's driver (abb_ros2) describes the arm with ABB's URDF, and its robot_state_publisher
puts ``link_1..link_6`` where that URDF says; a viewer, MoveIt and the controller manager
know the arm by those frames. This module is that URDF in numbers (no ROS, no XML parser):

Source: PickNikRobotics/abb_ros2, commit 0705714217c2e3edafba4d3a556f08d1a0949908 (the
file's last change 6fe7fbd, "Add ABB IRB4600 robot descriptions (#21)"),
``robot_specific_config/abb_irb4600_support/urdf/irb4600_60_205_macro.xacro``:

==================  ===========  ======================  =========  ===========  ==========
joint (L)           parent       origin xyz (rpy = 0)    axis       limits (rad)  velocity
==================  ===========  ======================  =========  ===========  ==========
joint_1 (L108-114)  base_link    0 0 0.495               0 0 1      -3.141 3.141  3.054
joint_2 (L115-121)  link_1       0.175 0 0               0 1 0      -1.570 2.617  3.054
joint_3 (L122-128)  link_2       0 0 0.9                 0 1 0      -3.141 1.308  3.054
joint_4 (L129-135)  link_3       0 0 0.175               1 0 0      -6.981 6.981  4.363
joint_5 (L136-142)  link_4       0.960 0 0               0 1 0      -2.181 2.094  4.363
joint_6 (L143-149)  link_5       0.135 0 0               1 0 0      -6.981 6.981  6.283
==================  ===========  ======================  =========  ===========  ==========

and the fixed frames of ROS-Industrial: ``base`` at base_link (joint ``base_link-base``,
L153-158), ``flange`` at link_6 (``joint_6-flange``, L161-166), ``tool0`` in ``flange``
at rpy (0, pi/2, 0) (``link_6-tool0``, L169-174). The top file ``irb4600_60_205.xacro``
adds only ``<ros2_control>`` (L13-20).

robot_state_publisher (ros/robot_state_publisher 3.3.3, rolling commit
e0f77e62457ae01f8dbf3b5c4cc62d15fa36dfad, ``src/robot_state_publisher.cpp``; its jazzy branch
was not in the mirror)
publishes, for each moving joint, the KDL segment pose ``origin * Rot(axis, q)`` from parent
to child link on /tf stamped with the joint state's stamp (``publishTransforms``, L253-276)
and each fixed joint once on /tf_static (``publishFixedTransforms``, L279-298).
:func:`joint_transforms`, :func:`fixed_transforms` and :func:`link_poses` give the same.

Against the paper's DH model (:mod:`ibvs_model.robot`, Table 1, eq. 4-7), found exactly
(``test_abb_urdf``: 1e-12 at thousands of q):

- the joint angles are the same, zero and sign: q_ABB = q (the paper's q shares ABB's zero
  pose and signs; ABB's limits are ours rounded down to 1 mrad);
- ABB's ``base_link`` is the paper's {O} and ABB's ``tool0`` is the paper's flange {E}:
  T_tool0^base_link(q) = T_E^O(q) (eq. 7) with no constant transform on either side;
- each link frame differs from the DH-framed link of :mod:`ibvs_model.urdf` by a constant
  (:func:`dh_link_offsets`), which is how this module draws our link solids in ABB's frames.

:func:`robot_description` is the URDF text of that arm (the stand-in for
robot_state_publisher publishes it): ABB's joints and frames, our link solids
(:func:`ibvs_model.mass_model.link_shapes`) moved into ABB's link frames, no tool (a cell's
URDF has none of ours: the viewers' node puts the tool's frames on /tf_static).

The lengths are ``params``' (RobotParams: L1, a1, L2, L3, L4, Lt); with the nominal IRB4600
they are ABB's numbers above exactly, with ``params.scaled(l2, l4)`` the arm of the
model-uncertainty study keeps ABB's frame layout with longer or shorter links.
"""

from dataclasses import replace
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._validate import as_array
from .mass_model import link_shapes, matrix_rpy
from .mass_model import rpy_matrix as rotation_of_rpy
from .robot import IRB4600, RobotParams
from .urdf import _link_xml, _material_xml, _num, _origin, BASE_RGBA, ROBOT_RGBA
from .urdf import joint_origins as dh_origins

#: ABB's six revolute joints, verbatim from the xacro (module docstring): name, parent,
#: child, origin xyz, axis, lower, upper, velocity. All origins have rpy = 0.
ABB_JOINTS = (
    ('joint_1', 'base_link', 'link_1', (0.0, 0.0, 0.495), (0.0, 0.0, 1.0), -3.141, 3.141, 3.054),
    ('joint_2', 'link_1', 'link_2', (0.175, 0.0, 0.0), (0.0, 1.0, 0.0), -1.570, 2.617, 3.054),
    ('joint_3', 'link_2', 'link_3', (0.0, 0.0, 0.9), (0.0, 1.0, 0.0), -3.141, 1.308, 3.054),
    ('joint_4', 'link_3', 'link_4', (0.0, 0.0, 0.175), (1.0, 0.0, 0.0), -6.981, 6.981, 4.363),
    ('joint_5', 'link_4', 'link_5', (0.960, 0.0, 0.0), (0.0, 1.0, 0.0), -2.181, 2.094, 4.363),
    ('joint_6', 'link_5', 'link_6', (0.135, 0.0, 0.0), (1.0, 0.0, 0.0), -6.981, 6.981, 6.283),
)
#: ABB's fixed joints: name, parent, child, xyz, rpy.
ABB_FIXED_JOINTS = (
    ('base_link-base', 'base_link', 'base', (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
    ('joint_6-flange', 'link_6', 'flange', (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
    ('link_6-tool0', 'flange', 'tool0', (0.0, 0.0, 0.0), (0.0, math.pi / 2.0, 0.0)),
)
BASE_FRAME = 'base_link'
TOOL_FRAME = 'tool0'
LINK_NAMES = tuple(j[2] for j in ABB_JOINTS)
JOINT_NAMES = tuple(j[0] for j in ABB_JOINTS)
#: (parent, child, T_child^parent) of a joint, as /tf and /tf_static carry it.
Transforms = list[tuple[str, str, NDArray[np.float64]]]


def rpy_matrix(rpy: ArrayLike) -> NDArray[np.float64]:
    """
    Return the 4x4 rotation of URDF ``rpy``: Rot_z(yaw) Rot_y(pitch) Rot_x(roll).

    Parameters
    ----------
    rpy : array_like, shape (3,)
        Roll, pitch, yaw (rad).

    Returns
    -------
    ndarray, shape (4, 4)

    """
    tf = np.eye(4)
    tf[:3, :3] = rotation_of_rpy([float(v) for v in rpy])
    return tf


def axis_rotation(axis: ArrayLike, angle: float) -> NDArray[np.float64]:
    """
    Return the 4x4 rotation by ``angle`` about the unit ``axis`` (a revolute joint's motion).

    Parameters
    ----------
    axis : array_like, shape (3,)
        The unit axis.
    angle : float
        The angle (rad).

    Returns
    -------
    ndarray, shape (4, 4)

    """
    x, y, z = (float(v) for v in axis)
    c, s = math.cos(angle), math.sin(angle)
    k = 1.0 - c
    tf = np.eye(4)
    tf[:3, :3] = [[c + x * x * k, x * y * k - z * s, x * z * k + y * s],
                  [y * x * k + z * s, c + y * y * k, y * z * k - x * s],
                  [z * x * k - y * s, z * y * k + x * s, c + z * z * k]]
    return tf


def _translation(xyz):
    tf = np.eye(4)
    tf[:3, 3] = xyz
    return tf


def joint_origins(params: RobotParams = IRB4600) -> list[tuple[float, float, float]]:
    """
    Return the origin xyz of joint_1..joint_6 in ABB's layout with the lengths of ``params``.

    (0, 0, L1), (a1, 0, 0), (0, 0, L2), (0, 0, L3), (L4, 0, 0), (Lt, 0, 0): ABB's numbers
    (:data:`ABB_JOINTS`) for the nominal IRB4600.

    Parameters
    ----------
    params : RobotParams
        The robot's geometry.

    Returns
    -------
    list of 6 (x, y, z)

    """
    p = params
    return [(0.0, 0.0, p.L1), (p.a1, 0.0, 0.0), (0.0, 0.0, p.L2), (0.0, 0.0, p.L3),
            (p.L4, 0.0, 0.0), (p.Lt, 0.0, 0.0)]


def joint_transforms(q: ArrayLike, params: RobotParams = IRB4600) -> Transforms:
    """
    Return (parent, child, T_child^parent) of the six revolute joints at ``q``: ABB's /tf.

    T = Trans(origin_i) Rot(axis_i, q_i), what robot_state_publisher's KDL segment gives
    (module docstring). q are the paper's angles, which are ABB's.

    Parameters
    ----------
    q : array_like, shape (6,)
        Joint angles (rad).
    params : RobotParams
        The robot's geometry.

    Returns
    -------
    list of (str, str, ndarray, shape (4, 4))

    """
    q = as_array(q, (6,), 'q')
    return [(parent, child, _translation(xyz) @ axis_rotation(axis, q[i]))
            for i, ((_, parent, child, _, axis, *_), xyz)
            in enumerate(zip(ABB_JOINTS, joint_origins(params)))]


def fixed_transforms() -> Transforms:
    """
    Return (parent, child, T) of ABB's fixed joints (base, flange, tool0): ABB's /tf_static.

    Returns
    -------
    list of (str, str, ndarray, shape (4, 4))

    """
    return [(parent, child, _translation(xyz) @ rpy_matrix(rpy))
            for _, parent, child, xyz, rpy in ABB_FIXED_JOINTS]


def link_poses(q: ArrayLike, params: RobotParams = IRB4600) -> dict[str, NDArray[np.float64]]:
    """
    Return {frame: T_frame^base_link} of ABB's frames at ``q``, as a tf listener composes them.

    base_link, link_1..link_6, base, flange and tool0.

    Parameters
    ----------
    q : array_like, shape (6,)
        Joint angles (rad).
    params : RobotParams
        The robot's geometry.

    Returns
    -------
    dict of str to ndarray, shape (4, 4)

    """
    poses = {BASE_FRAME: np.eye(4)}
    for parent, child, tf in joint_transforms(q, params) + fixed_transforms():
        poses[child] = poses[parent] @ tf
    return poses


def tool0_pose(q: ArrayLike, params: RobotParams = IRB4600) -> NDArray[np.float64]:
    """
    Return T_tool0^base_link(q) of ABB's URDF, which is the paper's T_E^O(q) (eq. 7).

    Parameters
    ----------
    q : array_like, shape (6,)
        Joint angles (rad).
    params : RobotParams
        The robot's geometry.

    Returns
    -------
    ndarray, shape (4, 4)

    """
    return link_poses(q, params)[TOOL_FRAME]


def dh_link_offsets(params: RobotParams = IRB4600) -> list[NDArray[np.float64]]:
    """
    Return C_i = (T_link_i^ABB)^-1 T_link_i^DH, constant in q, for link_1..link_6.

    T_link_i^DH is the frame of ``link_i`` in :mod:`ibvs_model.urdf` (DH frame {i-1} turned
    by joint i); both turn with joint i about the same axis line, so C_i does not depend
    on q (checked by test). A solid placed at X in our link_i is at C_i X in ABB's.

    Parameters
    ----------
    params : RobotParams
        The robot's geometry.

    Returns
    -------
    list of 6 ndarray, shape (4, 4)

    """
    abb = joint_transforms(np.zeros(6), params)
    dh = dh_origins(params)
    out = []
    t_abb, t_dh = np.eye(4), np.eye(4)
    for i in range(6):
        t_abb = t_abb @ abb[i][2]
        t_dh = t_dh @ dh[i]
        out.append(np.linalg.inv(t_abb) @ t_dh)
    return out


def robot_description(params: RobotParams = IRB4600) -> str:
    """
    Return the URDF text of the arm in ABB's frames, as the cell's /robot_description has it.

    ABB's joints (names, frames, axes, :data:`ABB_FIXED_JOINTS`) with the lengths of
    ``params``, the joint limits and speeds of ``params`` (ABB's rounded to 1 mrad in their
    file) and our link solids as visuals (no meshes a viewer would have to find, no
    inertials: robot_state_publisher and viewers need none). No tool.

    Parameters
    ----------
    params : RobotParams
        The robot's geometry.

    Returns
    -------
    str
        The URDF.

    """
    shapes = link_shapes(params)
    offsets = [np.eye(4)] + dh_link_offsets(params)
    lines = ['<?xml version="1.0"?>',
             '<!-- Generated by ibvs_model.abb_urdf.robot_description: the IRB 4600-60/2.05 in'
             " the frames of abb_ros2's irb4600_60_205_macro.xacro; do not edit. -->",
             '<robot name="abb_irb4600_60_205">']
    lines += _material_xml('robot_grey', ROBOT_RGBA)
    lines += _material_xml('base_grey', BASE_RGBA)
    for k, link in enumerate((BASE_FRAME,) + LINK_NAMES):
        solids = []
        for solid in shapes[link]:
            tf = offsets[k] @ _translation(solid.xyz) @ rpy_matrix(solid.rpy)
            solids.append(replace(solid, xyz=tuple(tf[:3, 3]), rpy=matrix_rpy(tf[:3, :3])))
        lines += _link_xml(link, solids, 'base_grey' if k == 0 else 'robot_grey', None)
    for (name, parent, child, _, axis, *_), xyz, lo, hi, speed in zip(
            ABB_JOINTS, joint_origins(params), params.q_min, params.q_max, params.qd_max):
        lines += [f'  <joint name="{name}" type="revolute">',
                  f'    <parent link="{parent}"/>',
                  f'    <child link="{child}"/>',
                  f'    {_origin(xyz)}',
                  f'    <axis xyz="{" ".join(_num(v) for v in axis)}"/>',
                  f'    <limit lower="{_num(lo)}" upper="{_num(hi)}" effort="0"'
                  f' velocity="{_num(speed)}"/>',
                  '  </joint>']
    for name, parent, child, xyz, rpy in ABB_FIXED_JOINTS:
        lines += [f'  <link name="{child}"/>',
                  f'  <joint name="{name}" type="fixed">',
                  f'    <parent link="{parent}"/>',
                  f'    <child link="{child}"/>',
                  f'    {_origin(xyz, rpy)}',
                  '  </joint>']
    lines.append('</robot>')
    return '\n'.join(lines) + '\n'
