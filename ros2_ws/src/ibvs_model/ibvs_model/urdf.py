"""
URDF of the IRB 4600-60/2.05 whose joint frames are the paper's DH frames (Table 1, eq. 4-7).

This is the simulator's internal model (PyBullet's bodies, dynamics and images): its link
frames never leave it. What the cell and its viewers know the arm by is ABB's URDF, whose
frames :mod:`ibvs_model.abb_urdf` gives (``tool0`` is the same {E} at the same q; each link
differs by a constant, :func:`ibvs_model.abb_urdf.dh_link_offsets`).

Pure Python (no ROS, no PyBullet): the simulator loads the text with PyBullet, a controller
may load it into any dynamics library, and ``robot_urdf(params.scaled(l2, l4))`` builds the
robot of the model-uncertainty study (paper Figure 13) with the same code.

Frames. URDF rotates a child link about an axis through the origin of its joint frame, and
DH frame {i} does not lie on joint i's axis. So link ``link_i`` carries the frame

    T_link_i^O = T_{i-1}^0(q) Rot_z(q_i + offset_i),

i.e. DH frame {i-1} turned by joint i (its origin is that of {i-1}, its z is joint i's axis),
and joint ``joint_{i+1}`` is placed in ``link_i`` at Trans_z(d_i) Trans_x(a_i) Rot_x(alpha_i)
Rot_z(offset_{i+1}): this reproduces A_i^{i-1} = Rot_z(theta_i) Trans_z(d_i) Trans_x(a_i)
Rot_x(alpha_i) (eq. 5) exactly. The fixed frame ``tool0`` is the flange {E} = DH frame {6}
(eq. 7). With the tool: ``screwdriver`` (same frame as tool0), ``marker_1`` at
P1 = [0, 0, 0]{E} and ``marker_2`` at P2 = [0, 0, L_tool / 2]{E} (eq. 8-9).

Shapes and mass: :mod:`ibvs_model.mass_model` (link solids sized after ABB's drawing, the
425 kg spread at one density, the tool's steel and ABS).

What the camera must see. The fiducials are spheres of radius ``scene.MARKER_RADIUS_M`` in
the colours ``scene.MARKER_RGB``. P1 is the flange centre, so link 6 is a thin quill
(5 mm across) from inside the wrist housing to P1, with no flange disc around P1; the
screwdriver is a 4 mm shaft. Seen from behind the wrist, these rods cross the near side of
a marker; being thin, they move its image centroid by less than 0.2 px. The wrist is drawn
slimmer than the real one (80 mm instead of about 200 mm across) and ends 95 mm before P1's
centre, so P1 is seen unless the camera looks at it from behind the wrist within about
40 deg of the tool axis.
The robot is light grey, the shaft dark grey: neither has the markers' red or blue hue.
A marker is drawn as a fine icosphere mesh (:data:`MARKER_MESH`, :func:`icosphere_obj`,
5120 faces, 0.01 % from a true sphere; :mod:`ibvs_model.mesh`) that :func:`write_urdf`
writes beside the URDF,
not as a URDF ``<sphere>``: PyBullet draws that one with a coarse polygon whose outline
moves the image centre by up to 0.15 px as joint 6 turns (measured), which the stereo
depth turns into centimetres (1 mm at 2.4 m is 0.014 px of disparity at HD720).

Joints. Ranges and speeds are ABB's (``RobotParams.q_min``, ``q_max``, ``qd_max``). ABB does
not publish motor torques; ``effort`` is the estimate of
:func:`ibvs_model.mass_model.joint_efforts`.
Damping and friction are zero, so computed torque linearises the plant (docs/design.md §5).
No collision shapes: the arm is torque controlled in free space and contact is outside the
paper's scope.
"""

import math
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np
from numpy.typing import NDArray

from .mass_model import inertials, joint_efforts, link_shapes, matrix_rpy, tool_shapes
from .mesh import icosphere_obj, MARKER_MESH
from .robot import IRB4600, RobotParams
from .scene import MARKER_RGB
from .tool import TOOL

ROBOT_RGBA = (0.82, 0.82, 0.80, 1.0)
BASE_RGBA = (0.62, 0.62, 0.62, 1.0)
SHAFT_RGBA = TOOL.shaft_rgba  # the tool's (:data:`.tool.TOOL`)
JOINT_NAMES = tuple(f'joint_{i}' for i in range(1, 7))
LINK_NAMES = ('base_link',) + tuple(f'link_{i}' for i in range(1, 7))


def _num(value):
    """Return the shortest text that reads back as the same float (no rounding)."""
    return repr(float(value))


def _fmt(values):
    return ' '.join(_num(v) for v in values)


def _origin(xyz, rpy=(0.0, 0.0, 0.0)):
    return f'<origin xyz="{_fmt(xyz)}" rpy="{_fmt(rpy)}"/>'


def _geometry(solid, marker_mesh=True):
    if solid.kind == 'box':
        return f'<box size="{_fmt(solid.size)}"/>'
    if solid.kind == 'cylinder':
        return f'<cylinder radius="{_num(solid.size[0])}" length="{_num(solid.size[1])}"/>'
    if not marker_mesh:
        return f'<sphere radius="{_num(solid.size[0])}"/>'
    # A sphere is drawn with the unit icosphere of MARKER_MESH (module docstring).
    scale = _fmt([solid.size[0]] * 3)
    return f'<mesh filename={quoteattr(MARKER_MESH)} scale="{scale}"/>'


def _principal_axes(inertia):
    """
    Return (rpy, diagonal inertia) of the principal axes of ``inertia``.

    PyBullet's inverse dynamics rejects an inertia whose products it rebuilds as
    I(i, j) != I(j, i) by one rounding error; written in principal axes, the tensor it builds
    is exactly symmetric. A tensor that is diagonal already is kept as it is. An eigenvector's
    sign is LAPACK's choice, which differs between CPU kernels: the first two axes are turned
    so that their largest component is positive and the third is their cross product (a
    right-handed frame), so that the frame is the same on every machine (to its last bits,
    which differ between CPU kernels).
    """
    if not np.any(inertia - np.diag(np.diag(inertia))):
        return (0.0, 0.0, 0.0), inertia
    moments, axes = np.linalg.eigh(inertia)
    for k in (0, 1):
        if axes[np.argmax(np.abs(axes[:, k])), k] < 0.0:
            axes[:, k] = -axes[:, k]
    axes[:, 2] = np.cross(axes[:, 0], axes[:, 1])
    return matrix_rpy(axes), np.diag(moments)


def _link_xml(name, solids, material, props, marker_mesh=True):
    lines = [f'  <link name={quoteattr(name)}>']
    if props is not None:
        mass, com, inertia = props
        rpy, inertia = _principal_axes(inertia)
        lines += [
            '    <inertial>',
            f'      {_origin(com, rpy)}',
            f'      <mass value="{_num(mass)}"/>',
            f'      <inertia ixx="{_num(inertia[0, 0])}" ixy="{_num(inertia[0, 1])}"'
            f' ixz="{_num(inertia[0, 2])}" iyy="{_num(inertia[1, 1])}"'
            f' iyz="{_num(inertia[1, 2])}" izz="{_num(inertia[2, 2])}"/>',
            '    </inertial>',
        ]
    for solid in solids:
        lines += [
            '    <visual>',
            f'      {_origin(solid.xyz, solid.rpy)}',
            f'      <geometry>{_geometry(solid, marker_mesh)}</geometry>',
            f'      <material name={quoteattr(material)}/>',
            '    </visual>',
        ]
    lines.append('  </link>')
    return lines


def _fixed_joint(name, parent, child, xyz=(0.0, 0.0, 0.0), rpy=(0.0, 0.0, 0.0)):
    return [
        f'  <joint name={quoteattr(name)} type="fixed">',
        f'    <parent link={quoteattr(parent)}/>',
        f'    <child link={quoteattr(child)}/>',
        f'    {_origin(xyz, rpy)}',
        '  </joint>',
    ]


def _dh_matrix(a, alpha, d, theta):
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct],
                     [st, ct * ca, -ct * sa, a * st],
                     [0.0, sa, ca, d],
                     [0.0, 0.0, 0.0, 1.0]])


def joint_origins(params: RobotParams = IRB4600) -> list[NDArray[np.float64]]:
    """
    Return the 4x4 origin of each URDF joint in its parent link: joint_1..joint_6, tool0.

    joint_1 sits at the base with Rot_z(offset_1); joint_{i+1} at Trans_z(d_i) Trans_x(a_i)
    Rot_x(alpha_i) Rot_z(offset_{i+1}) in link_i; tool0 at Trans_z(d_6) Trans_x(a_6)
    Rot_x(alpha_6) in link_6 (the DH transform of eq. 5 with theta = 0, split at the joint).

    Parameters
    ----------
    params : RobotParams
        The robot's geometry.

    Returns
    -------
    list of 7 ndarray, shape (4, 4)
        The origins of joint_1..joint_6 and tool0.

    """
    dh = params.dh_table()
    origins = []
    prev = np.eye(4)
    for a, alpha, d, offset in dh:
        origins.append(prev @ _dh_matrix(0.0, 0.0, 0.0, offset))
        prev = _dh_matrix(a, alpha, d, 0.0)
    origins.append(prev)
    return origins


def _material_xml(name, rgba):
    return [f'  <material name={quoteattr(name)}><color rgba="{_fmt(rgba)}"/></material>']


def robot_urdf(params: RobotParams = IRB4600, with_tool: bool = True,
               marker_mesh: bool = True) -> str:
    """
    Return the URDF text of the IRB 4600 of ``params`` (any RobotParams, e.g. scaled).

    Links base_link, link_1..link_6, tool0 ({E}); with the tool also screwdriver, marker_1
    (P1) and marker_2 (P2). Joints joint_1..joint_6 (ibvs_common.contract.JOINT_NAMES).
    The markers' visuals refer to the mesh :data:`MARKER_MESH` beside the URDF (relative
    file name): :func:`write_urdf` writes both. ``marker_mesh=False`` draws them as URDF
    ``<sphere>`` instead, for a viewer (RViz, Foxglove) that cannot reach files beside it.

    Parameters
    ----------
    params : RobotParams
        The robot's geometry.
    with_tool : bool
        Add the screwdriver and the markers.
    marker_mesh : bool
        Draw the markers with :data:`MARKER_MESH` rather than URDF spheres.

    Returns
    -------
    str
        The URDF.

    """
    shapes = link_shapes(params)
    props = inertials(params, with_tool)
    efforts = joint_efforts(params, with_tool)
    origins = joint_origins(params)
    marker_rgba = [tuple(c / 255.0 for c in rgb) + (1.0,) for rgb in MARKER_RGB]
    lines = ['<?xml version="1.0"?>',
             '<!-- Generated by ibvs_model.urdf.robot_urdf: do not edit; see its docstring'
             ' for the origin of every number. -->',
             f'<robot name="irb4600_60_205{"_screwdriver" if with_tool else ""}">']
    lines += _material_xml('robot_grey', ROBOT_RGBA)
    lines += _material_xml('base_grey', BASE_RGBA)
    if with_tool:
        lines += _material_xml('shaft_grey', SHAFT_RGBA)
        lines += _material_xml('marker_1_colour', marker_rgba[0])
        lines += _material_xml('marker_2_colour', marker_rgba[1])
    lines += _link_xml('base_link', shapes['base_link'], 'base_grey', props['base_link'])
    parent = 'base_link'
    for i in range(6):
        link = LINK_NAMES[i + 1]
        lines += _link_xml(link, shapes[link], 'robot_grey', props[link])
        tf = origins[i]
        lines += [
            f'  <joint name={quoteattr(JOINT_NAMES[i])} type="revolute">',
            f'    <parent link={quoteattr(parent)}/>',
            f'    <child link={quoteattr(link)}/>',
            f'    {_origin(tf[:3, 3], matrix_rpy(tf[:3, :3]))}',
            '    <axis xyz="0 0 1"/>',
            f'    <limit lower="{_num(params.q_min[i])}" upper="{_num(params.q_max[i])}"'
            f' effort="{efforts[i]:.6g}" velocity="{_num(params.qd_max[i])}"/>',
            '    <dynamics damping="0" friction="0"/>',
            '  </joint>',
        ]
        parent = link
    tf = origins[6]
    # tool0 is a frame only; PyBullet gives a link without <inertial> 1 kg and unit inertia.
    lines += _link_xml('tool0', [], '', (0.0, np.zeros(3), np.zeros((3, 3))))
    lines += _fixed_joint('joint_tool0', 'link_6', 'tool0', tf[:3, 3], matrix_rpy(tf[:3, :3]))
    if with_tool:
        tool = tool_shapes(params)
        lines += _link_xml('screwdriver', tool['screwdriver'], 'shaft_grey',
                           props['screwdriver'])
        lines += _fixed_joint('joint_screwdriver', 'tool0', 'screwdriver')
        for k, xyz in enumerate(params.fiducials_E, start=1):
            name = f'marker_{k}'
            lines += _link_xml(name, tool[name], f'{name}_colour', props[name], marker_mesh)
            lines += _fixed_joint(f'joint_{name}', 'tool0', name, xyz)
    lines.append('</robot>')
    return '\n'.join(lines) + '\n'


def write_urdf(path: str | Path, params: RobotParams = IRB4600,
               with_tool: bool = True) -> Path:
    """
    Write :func:`robot_urdf` to ``path`` and return the path.

    With the tool, the marker mesh :data:`MARKER_MESH` (:func:`icosphere_obj`) is written
    into the same folder.

    Parameters
    ----------
    path : str or pathlib.Path
        The URDF file to write.
    params : RobotParams
        The robot's geometry.
    with_tool : bool
        Add the screwdriver and the markers.

    Returns
    -------
    pathlib.Path
        ``path``.

    """
    path = Path(path)
    path.write_text(robot_urdf(params, with_tool))
    if with_tool:
        (path.parent / MARKER_MESH).write_text(icosphere_obj())
    return path
