"""
Masses, centres of mass, inertias and torque limits of the IRB 4600 and the tool (no ROS).

ABB publishes neither link masses nor inertias (docs/design.md §5), only the
total robot mass, 425 kg (IRB 4600-60/2.05 product specification), and a dimension drawing.
Each link is drawn as a few boxes and cylinders sized after that drawing (the numbers in
:func:`link_shapes`, each with its reason). The 425 kg are spread over all these solids at
one uniform density, so a link's mass is proportional to its envelope volume, its centre of
mass is the volume centroid and its inertia that of uniform solids (overlapping solids count
twice; this is an estimate good to tens of per cent, not a datum). The tool is not part of
the 425 kg: a steel shaft (7850 kg/m^3) and two solid ABS spheres (1050 kg/m^3).

Joint torque limits. ABB does not publish motor torques; :func:`joint_efforts` is an
estimate: 1.5 times an upper bound of the static gravity torque with the rated 60 kg payload
0.2 m beyond the flange, computed from the masses above (lever arms bounded by the sum of the
link offsets, so the bound holds in every pose; for the vertical joint 1 the same budget buys
about 1 g at the centres of mass). :mod:`ibvs_model.urdf` writes all of it into the URDF.
"""

from collections.abc import Sequence
from dataclasses import dataclass
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .robot import IRB4600, RobotParams
from .scene import MARKER_RADIUS_M
from .tool import TOOL

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
#: Radius of the screwdriver shaft (the tool's: :data:`.tool.TOOL`) and of the link-6
#: quill that carries P1 (the simulated arm's), m.
SHAFT_RADIUS_M = TOOL.shaft_radius_m
QUILL_RADIUS_M = 0.0025
GRAVITY = 9.81


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

    def volume(self) -> float:
        """Return the volume, m^3."""
        if self.kind == 'box':
            return float(np.prod(self.size))
        if self.kind == 'cylinder':
            r, length = self.size
            return math.pi * r * r * length
        return 4.0 / 3.0 * math.pi * self.size[0] ** 3

    def inertia(self, mass: float) -> NDArray[np.float64]:
        """
        Return the inertia of a uniform solid of ``mass`` about its centre, in link axes.

        Parameters
        ----------
        mass : float
            The solid's mass (kg).

        Returns
        -------
        ndarray, shape (3, 3)
            The inertia tensor (kg m^2).

        """
        if self.kind == 'box':
            x, y, z = self.size
            own = mass / 12.0 * np.diag([y * y + z * z, x * x + z * z, x * x + y * y])
        elif self.kind == 'cylinder':
            r, length = self.size
            side = mass * (3.0 * r * r + length * length) / 12.0
            own = np.diag([side, side, mass * r * r / 2.0])
        else:
            own = np.eye(3) * 0.4 * mass * self.size[0] ** 2
        rot = rpy_matrix(self.rpy)
        return rot @ own @ rot.T


def rpy_matrix(rpy: Sequence[float]) -> NDArray[np.float64]:
    """
    Return R = Rot_z(yaw) Rot_y(pitch) Rot_x(roll), URDF's fixed-axis rpy.

    Parameters
    ----------
    rpy : sequence of 3 float
        Roll, pitch, yaw (rad).

    Returns
    -------
    ndarray, shape (3, 3)
        R.

    """
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = (math.cos(r), math.sin(r), math.cos(p), math.sin(p),
                              math.cos(y), math.sin(y))
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def matrix_rpy(rot: ArrayLike) -> tuple[float, float, float]:
    """
    Return URDF rpy of a rotation matrix (inverse of :func:`rpy_matrix`).

    Parameters
    ----------
    rot : array_like, shape (3, 3)
        A rotation matrix.

    Returns
    -------
    tuple of 3 float
        Roll, pitch, yaw (rad); roll = 0 at gimbal lock.

    """
    pitch = math.atan2(-rot[2, 0], math.hypot(rot[0, 0], rot[1, 0]))
    if abs(math.cos(pitch)) < 1e-9:
        # Gimbal lock: put the whole rotation about z into yaw, roll = 0.
        return 0.0, pitch, math.atan2(-rot[0, 1], rot[1, 1])
    return (math.atan2(rot[2, 1], rot[2, 2]), pitch, math.atan2(rot[1, 0], rot[0, 0]))


_ALONG_X = (0.0, math.pi / 2.0, 0.0)   # a cylinder's z turned onto the link's x
_ALONG_Y = (-math.pi / 2.0, 0.0, 0.0)  # a cylinder's z turned onto the link's y


def link_shapes(params: RobotParams) -> dict[str, list[Solid]]:
    """
    Return the solids of each link, sized after ABB's drawing.

    Lengths along the arm follow ``params`` (so scaled robots stretch their links); the
    cross-sections are rounded envelope dimensions of the IRB 4600 drawing.

    Parameters
    ----------
    params : RobotParams
        The robot's geometry.

    Returns
    -------
    dict of str to list of Solid
        Solids by link name, base_link and link_1..link_6.

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


def tool_shapes(params: RobotParams) -> dict[str, list[Solid]]:
    """
    Return the screwdriver shaft and the two marker spheres, in the flange frame {E}.

    Parameters
    ----------
    params : RobotParams
        The robot's geometry (``L_tool``).

    Returns
    -------
    dict of str to list of Solid
        Solids of 'screwdriver', 'marker_1' and 'marker_2'.

    """
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


def inertials(params: RobotParams = IRB4600, with_tool: bool = True
              ) -> dict[str, tuple[float, NDArray[np.float64], NDArray[np.float64]]]:
    """
    Return the mass properties of every link (and tool part) in its own frame.

    Robot links share one density, 425 kg / (total solid volume); tool parts are steel
    and ABS (module docstring).

    Parameters
    ----------
    params : RobotParams
        The robot's geometry.
    with_tool : bool
        Include the screwdriver and the two markers.

    Returns
    -------
    dict of str to tuple
        By link name: (mass (kg), centre of mass (3,) (m), inertia (3, 3) about it (kg m^2)).

    """
    shapes = link_shapes(params)
    density = ROBOT_MASS_KG / sum(s.volume() for solids in shapes.values() for s in solids)
    out = {name: _mass_properties(solids, density) for name, solids in shapes.items()}
    if with_tool:
        tool = tool_shapes(params)
        out['screwdriver'] = _mass_properties(tool['screwdriver'], STEEL_DENSITY)
        out['marker_1'] = _mass_properties(tool['marker_1'], ABS_DENSITY)
        out['marker_2'] = _mass_properties(tool['marker_2'], ABS_DENSITY)
    return out


def _joint_offsets(params):
    """Return the DH translation (d_i, a_i) lengths |(a_i, d_i)| of joints 1..6."""
    return [math.hypot(a, d) for a, _, d, _ in params.dh_table()]


def joint_efforts(params: RobotParams = IRB4600, with_tool: bool = True) -> list[float]:
    """
    Return the estimated torque limit of each joint, N m (module docstring).

    For joint j: 1.5 * g * sum over the links it carries of m_k * (bound on the distance from
    joint j's axis to link k's centre of mass), plus the rated payload beyond the flange.

    Parameters
    ----------
    params : RobotParams
        The robot's geometry.
    with_tool : bool
        Count the tool's mass.

    Returns
    -------
    list of 6 float
        Torque limits of joints 1..6 (N m).

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
