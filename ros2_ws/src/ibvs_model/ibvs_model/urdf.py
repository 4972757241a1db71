"""
URDF of the IRB 4600-60/2.05 whose joint frames are the paper's DH frames (Table 1, eq. 4-7).

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

Shapes and mass. ABB publishes neither link masses nor inertias (DESIGN section 5), only the
total robot mass, 425 kg (IRB 4600-60/2.05 product specification), and a dimension drawing.
Each link is drawn as a few boxes and cylinders sized after that drawing (the numbers in
:func:`_link_shapes`, each with its reason). The 425 kg are spread over all these solids at
one uniform density, so a link's mass is proportional to its envelope volume, its centre of
mass is the volume centroid and its inertia that of uniform solids (overlapping solids count
twice; this is an estimate good to tens of per cent, not a datum). The tool is not part of
the 425 kg: a steel shaft (7850 kg/m^3) and two solid ABS spheres (1050 kg/m^3).

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
5120 faces, 0.01 % from a true sphere) that :func:`write_urdf` writes beside the URDF,
not as a URDF ``<sphere>``: PyBullet draws that one with a coarse polygon whose outline
moves the image centre by up to 0.15 px as joint 6 turns (measured), which the stereo
depth turns into centimetres (1 mm at 2.4 m is 0.014 px of disparity at HD720).

Joints. Ranges and speeds are ABB's (``RobotParams.q_min``, ``q_max``, ``qd_max``). ABB does
not publish motor torques; ``effort`` is an estimate: 1.5 times an upper bound of the static
gravity torque with the rated 60 kg payload 0.2 m beyond the flange, computed from the
masses above (lever arms bounded by the sum of the link offsets, so the bound holds in every
pose; for the vertical joint 1 the same budget buys about 1 g at the centres of mass).
Damping and friction are zero, so computed torque linearises the plant (DESIGN section 5).
No collision shapes: the arm is torque controlled in free space and contact is outside the
paper's scope.
"""

from dataclasses import dataclass
import math
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from .robot import IRB4600
from .scene import MARKER_RADIUS_M, MARKER_RGB

#: Total mass of the IRB 4600-60/2.05 (ABB product specification), kg.
ROBOT_MASS_KG = 425.0
#: Rated payload of the IRB 4600-60 (used only for the effort estimate), kg.
RATED_PAYLOAD_KG = 60.0
#: Assumed distance of the rated payload's centre of mass beyond the flange, m.
PAYLOAD_OFFSET_M = 0.2
#: Effort = this factor times the bound on the static gravity torque.
EFFORT_MARGIN = 1.5
#: Density of the screwdriver's steel shaft and of the ABS marker spheres, kg/m^3.
STEEL_DENSITY = 7850.0
ABS_DENSITY = 1050.0
#: Radius of the screwdriver shaft and of the link-6 quill that carries P1, m.
SHAFT_RADIUS_M = 0.002
QUILL_RADIUS_M = 0.0025
GRAVITY = 9.81

ROBOT_RGBA = (0.82, 0.82, 0.80, 1.0)
BASE_RGBA = (0.62, 0.62, 0.62, 1.0)
SHAFT_RGBA = (0.35, 0.35, 0.35, 1.0)
#: File name of the marker sphere mesh (unit radius), written beside the URDF.
MARKER_MESH = 'marker_sphere.obj'
#: Subdivisions of the icosahedron: 4 gives 5120 faces, edges of about 4 degrees of arc.
MARKER_MESH_SUBDIVISIONS = 4

JOINT_NAMES = tuple(f'joint_{i}' for i in range(1, 7))
LINK_NAMES = ('base_link',) + tuple(f'link_{i}' for i in range(1, 7))


@dataclass(frozen=True)
class Solid:
    """
    A box, cylinder or sphere of a link, in the link frame.

    ``size``: box (x, y, z) edge lengths; cylinder (radius, length) along its own z;
    sphere (radius,). ``rpy`` turns the solid's own axes into the link frame (URDF order).
    """

    kind: str
    size: tuple
    xyz: tuple = (0.0, 0.0, 0.0)
    rpy: tuple = (0.0, 0.0, 0.0)

    def volume(self):
        """Return the volume, m^3."""
        if self.kind == 'box':
            return float(np.prod(self.size))
        if self.kind == 'cylinder':
            r, length = self.size
            return math.pi * r * r * length
        return 4.0 / 3.0 * math.pi * self.size[0] ** 3

    def inertia(self, mass):
        """Return the 3x3 inertia of a uniform solid of ``mass`` about its centre, link axes."""
        if self.kind == 'box':
            x, y, z = self.size
            own = mass / 12.0 * np.diag([y * y + z * z, x * x + z * z, x * x + y * y])
        elif self.kind == 'cylinder':
            r, length = self.size
            side = mass * (3.0 * r * r + length * length) / 12.0
            own = np.diag([side, side, mass * r * r / 2.0])
        else:
            own = np.eye(3) * 0.4 * mass * self.size[0] ** 2
        rot = _rpy_matrix(self.rpy)
        return rot @ own @ rot.T


def _rpy_matrix(rpy):
    """Return R = Rot_z(yaw) Rot_y(pitch) Rot_x(roll), URDF's fixed-axis rpy."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = (math.cos(r), math.sin(r), math.cos(p), math.sin(p),
                              math.cos(y), math.sin(y))
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def _matrix_rpy(rot):
    """Return URDF rpy of a rotation matrix (inverse of :func:`_rpy_matrix`)."""
    pitch = math.atan2(-rot[2, 0], math.hypot(rot[0, 0], rot[1, 0]))
    if abs(math.cos(pitch)) < 1e-9:
        # Gimbal lock: put the whole rotation about z into yaw, roll = 0.
        return 0.0, pitch, math.atan2(-rot[0, 1], rot[1, 1])
    return (math.atan2(rot[2, 1], rot[2, 2]), pitch, math.atan2(rot[1, 0], rot[0, 0]))


_ALONG_X = (0.0, math.pi / 2.0, 0.0)   # a cylinder's z turned onto the link's x
_ALONG_Y = (-math.pi / 2.0, 0.0, 0.0)  # a cylinder's z turned onto the link's y


def _link_shapes(params):
    """
    Return the solids of each link (dict name -> list of Solid), sized after ABB's drawing.

    Lengths along the arm follow ``params`` (so scaled robots stretch their links); the
    cross-sections are rounded envelope dimensions of the IRB 4600 drawing.
    """
    a1, l1, l2, l3, l4, lt = params.a1, params.L1, params.L2, params.L3, params.L4, params.Lt
    base_h = 0.2  # height of the fixed foot; footprint about 0.5 m x 0.5 m
    turntable_top = base_h + 0.14
    tube = max(l4 - 0.24, 0.02)  # forearm tube from 0.10 m to the fork, 0.14 m before L4
    quill = max(lt - 0.03, 0.01)
    return {
        'base_link': [Solid('box', (0.50, 0.50, base_h), (0.0, 0.0, base_h / 2))],
        # Turntable (radius 0.24 m) on the foot, and the shoulder housing that carries
        # joint 2 at (a1, 0, L1); the joint-2 hub's axis is the link's y (DH z1).
        'link_1': [
            Solid('cylinder', (0.24, 0.14), (0.0, 0.0, base_h + 0.07)),
            Solid('box', (a1 + 0.20, 0.36, l1 + 0.12 - turntable_top),
                  (a1 / 2.0, 0.0, (l1 + 0.12 + turntable_top) / 2.0)),
        ],
        # Lower arm: frame at joint 2, x towards the elbow (length L2), z = joint-2 axis.
        'link_2': [
            Solid('cylinder', (0.14, 0.32)),
            Solid('box', (l2, 0.18, 0.16), (l2 / 2.0, 0.0, 0.0)),
        ],
        # Elbow: frame at joint 3 (z its axis); the forearm axis (DH z3) is the link's y,
        # through (L3, 0, 0). The housing holds the wrist motors behind the elbow (y < 0).
        'link_3': [
            Solid('cylinder', (0.12, 0.26)),
            Solid('box', (l3 + 0.22, 0.40, 0.24), (l3 / 2.0, -0.10, 0.0)),
        ],
        # Forearm tube along z (joint-4 axis) towards the wrist centre at z = L4, and the
        # wrist fork: two plates either side of the joint-5 axis (the link's -y), ending in
        # hubs of radius 0.04 m around the wrist centre.
        'link_4': [
            Solid('cylinder', (0.08, tube), (0.0, 0.0, 0.10 + tube / 2.0)),
            Solid('box', (0.08, 0.015, 0.16), (0.0, 0.0525, l4 - 0.08)),
            Solid('box', (0.08, 0.015, 0.16), (0.0, -0.0525, l4 - 0.08)),
            Solid('cylinder', (0.04, 0.015), (0.0, 0.0525, l4), _ALONG_Y),
            Solid('cylinder', (0.04, 0.015), (0.0, -0.0525, l4), _ALONG_Y),
        ],
        # Wrist housing around the joint-5 axis (the link's z) between the fork plates.
        # Radius 0.04 m leaves 95 mm to P1's centre (the tool axis is the link's y): the
        # wrist is drawn slimmer than the real one (about 0.2 m across) so that P1 at the
        # flange centre stays visible from the side, e.g. at the paper's scenario 1 start.
        'link_5': [Solid('cylinder', (0.04, 0.09))],
        # Joint-6 rotor inside the wrist housing, and the quill that carries P1 at z = Lt:
        # no flange disc around P1 (it would hide the marker).
        'link_6': [
            Solid('cylinder', (0.025, 0.03), (0.0, 0.0, 0.015)),
            Solid('cylinder', (QUILL_RADIUS_M, quill), (0.0, 0.0, lt - quill / 2.0)),
        ],
    }


def _tool_shapes(params):
    """Return the screwdriver shaft and the two marker spheres, in the flange frame {E}."""
    return {
        'screwdriver': [Solid('cylinder', (SHAFT_RADIUS_M, params.L_tool),
                              (0.0, 0.0, params.L_tool / 2.0))],
        'marker_1': [Solid('sphere', (MARKER_RADIUS_M,))],
        'marker_2': [Solid('sphere', (MARKER_RADIUS_M,))],
    }


def _mass_properties(solids, density):
    """Return (mass, centre of mass, inertia about it) of uniform solids of ``density``."""
    masses = np.array([s.volume() * density for s in solids])
    mass = float(masses.sum())
    centres = np.array([s.xyz for s in solids], dtype=float)
    com = masses @ centres / mass
    inertia = np.zeros((3, 3))
    for s, m, c in zip(solids, masses, centres):
        r = c - com
        inertia += s.inertia(m) + m * (np.dot(r, r) * np.eye(3) - np.outer(r, r))
    return mass, com, inertia


def inertials(params=IRB4600, with_tool=True):
    """
    Return {link name: (mass kg, centre of mass (3,), inertia 3x3)} in each link's frame.

    Robot links share one density, 425 kg / (total solid volume); tool parts are steel
    and ABS (module docstring).
    """
    shapes = _link_shapes(params)
    density = ROBOT_MASS_KG / sum(s.volume() for solids in shapes.values() for s in solids)
    out = {name: _mass_properties(solids, density) for name, solids in shapes.items()}
    if with_tool:
        tool = _tool_shapes(params)
        out['screwdriver'] = _mass_properties(tool['screwdriver'], STEEL_DENSITY)
        out['marker_1'] = _mass_properties(tool['marker_1'], ABS_DENSITY)
        out['marker_2'] = _mass_properties(tool['marker_2'], ABS_DENSITY)
    return out


def _joint_offsets(params):
    """Return the DH translation (d_i, a_i) lengths |(a_i, d_i)| of joints 1..6."""
    return [math.hypot(a, d) for a, _, d, _ in params.dh_table()]


def joint_efforts(params=IRB4600, with_tool=True):
    """
    Return the estimated torque limit of each joint, N m (module docstring).

    For joint j: 1.5 * g * sum over the links it carries of m_k * (bound on the distance from
    joint j's axis to link k's centre of mass), plus the rated payload beyond the flange.
    """
    props = inertials(params, with_tool)
    seg = _joint_offsets(params)
    masses = [props[f'link_{k}'][0] for k in range(1, 7)]
    coms = [float(np.linalg.norm(props[f'link_{k}'][1])) for k in range(1, 7)]
    tool_mass = sum(props[n][0] for n in ('screwdriver', 'marker_1', 'marker_2')
                    if n in props)
    efforts = []
    for j in range(6):
        torque = 0.0
        for k in range(j, 6):
            # link_{k+1} hangs from joint j+1's origin via the offsets of joints j+1..k.
            torque += masses[k] * (sum(seg[j:k]) + coms[k])
        reach = sum(seg[j:6])
        torque += tool_mass * (reach + params.L_tool)
        torque += RATED_PAYLOAD_KG * (reach + PAYLOAD_OFFSET_M)
        efforts.append(EFFORT_MARGIN * GRAVITY * torque)
    return efforts


def _num(value):
    """Return the shortest text that reads back as the same float (no rounding)."""
    return repr(float(value))


def _fmt(values):
    return ' '.join(_num(v) for v in values)


def _origin(xyz, rpy=(0.0, 0.0, 0.0)):
    return f'<origin xyz="{_fmt(xyz)}" rpy="{_fmt(rpy)}"/>'


def _geometry(solid):
    if solid.kind == 'box':
        return f'<box size="{_fmt(solid.size)}"/>'
    if solid.kind == 'cylinder':
        return f'<cylinder radius="{_num(solid.size[0])}" length="{_num(solid.size[1])}"/>'
    # A sphere is drawn with the unit icosphere of MARKER_MESH (module docstring).
    scale = _fmt([solid.size[0]] * 3)
    return f'<mesh filename={quoteattr(MARKER_MESH)} scale="{scale}"/>'


def icosphere_obj(subdivisions=MARKER_MESH_SUBDIVISIONS):
    """
    Return a Wavefront OBJ of the unit sphere: an icosahedron subdivided ``subdivisions`` times.

    Each subdivision splits every triangle into four, with the new vertices pushed out to
    the sphere; the vertex normals are the vertex positions (smooth shading). The faces are
    20 * 4^subdivisions, wound counter-clockwise seen from outside.
    """
    if not (isinstance(subdivisions, int) and 0 <= subdivisions <= 6):
        raise ValueError(f'subdivisions must be an int in [0, 6], got {subdivisions!r}')
    t = (1.0 + math.sqrt(5.0)) / 2.0
    vertices = [np.array(v, float) / math.hypot(1.0, t) for v in (
        (-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
        (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1))]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9),
             (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2),
             (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
             (8, 6, 7), (9, 8, 1)]
    for _ in range(subdivisions):
        midpoints = {}

        def midpoint(a, b):
            key = (min(a, b), max(a, b))
            if key not in midpoints:
                m = vertices[a] + vertices[b]
                vertices.append(m / np.linalg.norm(m))
                midpoints[key] = len(vertices) - 1
            return midpoints[key]

        refined = []
        for a, b, c in faces:
            ab, bc, ca = midpoint(a, b), midpoint(b, c), midpoint(c, a)
            refined += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = refined
    lines = [f'# Unit icosphere, {len(faces)} faces: ibvs_model.urdf.icosphere_obj'
             f'({subdivisions}).']
    lines += ['v {:.6f} {:.6f} {:.6f}'.format(*v) for v in vertices]
    lines += ['vn {:.6f} {:.6f} {:.6f}'.format(*v) for v in vertices]
    lines += [f'f {a + 1}//{a + 1} {b + 1}//{b + 1} {c + 1}//{c + 1}' for a, b, c in faces]
    return '\n'.join(lines) + '\n'


def _principal_axes(inertia):
    """
    Return (rpy, diagonal inertia) of the principal axes of ``inertia``.

    PyBullet's inverse dynamics rejects an inertia whose products it rebuilds as
    I(i, j) != I(j, i) by one rounding error; written in principal axes, the tensor it builds
    is exactly symmetric. A tensor that is diagonal already is kept as it is.
    """
    if not np.any(inertia - np.diag(np.diag(inertia))):
        return (0.0, 0.0, 0.0), inertia
    moments, axes = np.linalg.eigh(inertia)
    if np.linalg.det(axes) < 0.0:
        axes[:, 0] = -axes[:, 0]
    return _matrix_rpy(axes), np.diag(moments)


def _link_xml(name, solids, material, props):
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
            f'      <geometry>{_geometry(solid)}</geometry>',
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


def joint_origins(params=IRB4600):
    """
    Return the 4x4 origin of each URDF joint in its parent link: joint_1..joint_6, tool0.

    joint_1 sits at the base with Rot_z(offset_1); joint_{i+1} at Trans_z(d_i) Trans_x(a_i)
    Rot_x(alpha_i) Rot_z(offset_{i+1}) in link_i; tool0 at Trans_z(d_6) Trans_x(a_6)
    Rot_x(alpha_6) in link_6 (the DH transform of eq. 5 with theta = 0, split at the joint).
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


def robot_urdf(params=IRB4600, with_tool=True):
    """
    Return the URDF text of the IRB 4600 of ``params`` (any RobotParams, e.g. scaled).

    Links base_link, link_1..link_6, tool0 ({E}); with the tool also screwdriver, marker_1
    (P1) and marker_2 (P2). Joints joint_1..joint_6 (ibvs_common.contract.JOINT_NAMES).
    The markers' visuals refer to the mesh :data:`MARKER_MESH` beside the URDF (relative
    file name): :func:`write_urdf` writes both.
    """
    shapes = _link_shapes(params)
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
            f'    {_origin(tf[:3, 3], _matrix_rpy(tf[:3, :3]))}',
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
    lines += _fixed_joint('joint_tool0', 'link_6', 'tool0', tf[:3, 3], _matrix_rpy(tf[:3, :3]))
    if with_tool:
        tool = _tool_shapes(params)
        lines += _link_xml('screwdriver', tool['screwdriver'], 'shaft_grey',
                           props['screwdriver'])
        lines += _fixed_joint('joint_screwdriver', 'tool0', 'screwdriver')
        for k, xyz in enumerate(params.fiducials_E, start=1):
            name = f'marker_{k}'
            lines += _link_xml(name, tool[name], f'{name}_colour', props[name])
            lines += _fixed_joint(f'joint_{name}', 'tool0', name, xyz)
    lines.append('</robot>')
    return '\n'.join(lines) + '\n'


def write_urdf(path, params=IRB4600, with_tool=True):
    """
    Write :func:`robot_urdf` to ``path`` and return the path (a :class:`pathlib.Path`).

    With the tool, the marker mesh :data:`MARKER_MESH` (:func:`icosphere_obj`) is written
    into the same folder.
    """
    path = Path(path)
    path.write_text(robot_urdf(params, with_tool))
    if with_tool:
        (path.parent / MARKER_MESH).write_text(icosphere_obj())
    return path
