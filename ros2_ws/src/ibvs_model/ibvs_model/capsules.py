"""
Capsules of the arm, the tool and the cell, and the distances between them (no PyBullet).

A capsule is a segment with a radius: every point within ``radius`` of the segment. The
distance between two capsules is the distance between their segments less both radii,
which the closest-point algorithm of Ericson (Real-Time Collision Detection, 2005,
5.1.9 "Closest points of two line segments") gives exactly; a plane's distance to a
capsule is the lower end's height above it less the radius. These bound the solids of
:func:`.mass_model.link_shapes` and :func:`.mass_model.tool_shapes` (the radii below cite
the solids they cover) and the cell of the simulator (``ibvs_sim.world``: the riser the
robot stands on, the floor ``mount_height_m`` below the base plane) plus the ZED 2 at the
camera eye, so that the safety envelope (``ibvs_control.envelope``) measures the arm's
clearance without a physics engine, as MoveIt Servo's collision monitor does with FCL
(moveit2 jazzy 4d84106, ``moveit_ros/moveit_servo/src/collision_monitor.cpp`` L98-171).
"""

from dataclasses import dataclass
import math

import numpy as np
from numpy.typing import ArrayLike

from .robot import IRB4600, joint_frames, RobotParams
from .tool import TOOL

#: Half the ZED 2's width (175 mm, Stereolabs' ZED 2 datasheet): a sphere of this radius
#: around the camera eye holds the whole enclosure whatever its orientation (m).
CAMERA_RADIUS_M = 0.0875
#: The riser's half side (``ibvs_sim.world.RISER_HALF_SIZE_M``, 0.4 m): a vertical capsule
#: of this radius stands for it (its faces; the corners stick out by 0.17 m) (m).
PEDESTAL_RADIUS_M = 0.4
#: Height of the robot's fixed foot above the base plane (``mass_model.link_shapes``:
#: base_h 0.2 m); the pedestal capsule ends there (m).
PEDESTAL_TOP_M = 0.2


@dataclass(frozen=True)
class Capsule:
    """A segment from ``a`` to ``b`` (m, in {O}) with a ``radius`` (m); a == b: a sphere."""

    name: str
    a: tuple
    b: tuple
    radius: float


def segment_distance(p0: ArrayLike, p1: ArrayLike, q0: ArrayLike, q1: ArrayLike) -> float:
    """
    Return the least distance between the segments p0-p1 and q0-q1.

    Ericson, Real-Time Collision Detection (2005), 5.1.9: the closest points
    p0 + s (p1 - p0), q0 + t (q1 - q0) with s, t clamped to [0, 1]; degenerate segments
    (points) included.

    Parameters
    ----------
    p0, p1, q0, q1 : array_like, shape (3,)
        End points (m).

    Returns
    -------
    float
        The distance (m), >= 0.

    """
    p0, p1, q0, q1 = (np.asarray(v, dtype=float) for v in (p0, p1, q0, q1))
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a, e, f = float(d1 @ d1), float(d2 @ d2), float(d2 @ r)
    eps = 1e-18
    if a <= eps and e <= eps:
        return float(np.linalg.norm(r))
    if a <= eps:
        s, t = 0.0, min(1.0, max(0.0, f / e))
    else:
        c = float(d1 @ r)
        if e <= eps:
            s, t = min(1.0, max(0.0, -c / a)), 0.0
        else:
            b = float(d1 @ d2)
            denom = a * e - b * b
            s = min(1.0, max(0.0, (b * f - c * e) / denom)) if denom > eps else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                s, t = min(1.0, max(0.0, -c / a)), 0.0
            elif t > 1.0:
                s, t = min(1.0, max(0.0, (b - c) / a)), 1.0
    return float(np.linalg.norm((p0 + s * d1) - (q0 + t * d2)))


def capsule_distance(c1: Capsule, c2: Capsule) -> float:
    """Return the clearance between two capsules (m; < 0: they overlap by that much)."""
    return segment_distance(c1.a, c1.b, c2.a, c2.b) - c1.radius - c2.radius


def plane_distance(capsule: Capsule, height: float) -> float:
    """Return the clearance of a capsule above the horizontal plane z = ``height`` (m)."""
    return min(capsule.a[2], capsule.b[2]) - height - capsule.radius


def arm_capsules(q: ArrayLike, params: RobotParams = IRB4600) -> list[Capsule]:
    """
    Return the capsules of the moving arm and the tool at joint angles ``q``.

    ================  ===========================================  ========================
    capsule           segment                                      radius (covers)
    ================  ===========================================  ========================
    upper_arm         joint 2 to joint 3 (L2)                      0.12 m: link_2's box
                                                                   0.18 x 0.16 (half
                                                                   diagonal)
    forearm           joint 3 to the wrist centre (L3, L4)          0.12 m: link_3's elbow
                                                                   hub, link_4's tube 0.08
    wrist             wrist centre to the flange (Lt)              0.07 m: link_4's fork
                                                                   (plates at 0.06 m)
    tool              flange (P1) to the tool tip (L_tool)         0.025 m: the markers
    ================  ===========================================  ========================

    Parameters
    ----------
    q : array_like, shape (6,)
        Joint angles (rad).
    params : RobotParams
        The robot's geometry.

    Returns
    -------
    list of Capsule
        In {O}.

    """
    frames = joint_frames(q, params)
    origin = frames[:, :3, 3]
    flange = frames[6]
    tip = flange[:3, 3] + params.L_tool * flange[:3, 2]
    return [Capsule('upper_arm', tuple(origin[1]), tuple(origin[2]), 0.12),
            Capsule('forearm', tuple(origin[2]), tuple(origin[4]), 0.12),
            Capsule('wrist', tuple(origin[4]), tuple(origin[6]), 0.07),
            Capsule('tool', tuple(origin[6]), tuple(tip), TOOL.marker_radius_m)]


@dataclass(frozen=True)
class Cell:
    """
    What stands around the arm: the pedestal, the floor (and a table, if any) and the camera.

    ``mount_height_m``: the base plane's height above the floor (the simulator's parameter
    of that name, default 0.5 m); ``table_height_m``: a work table's top in {O} (None: no
    table, the simulator has none); ``camera_eye``: the camera's position in {O}.
    """

    mount_height_m: float = 0.5
    camera_eye: tuple = (0.3, -1.6, 1.2)
    table_height_m: float | None = None

    def capsules(self) -> list[Capsule]:
        """Return the pedestal and the camera as capsules in {O}."""
        return [Capsule('pedestal', (0.0, 0.0, -self.mount_height_m), (0.0, 0.0, PEDESTAL_TOP_M),
                        PEDESTAL_RADIUS_M),
                Capsule('camera', tuple(self.camera_eye), tuple(self.camera_eye),
                        CAMERA_RADIUS_M)]

    def planes(self) -> list[tuple[str, float]]:
        """Return the horizontal planes: (name, height in {O}) pairs."""
        planes = [('floor', -self.mount_height_m)]
        if self.table_height_m is not None:
            planes.append(('table', float(self.table_height_m)))
        return planes


#: Pairs of arm capsules that can meet (not neighbours on the chain), for self-collision.
SELF_PAIRS = (('tool', 'upper_arm'), ('wrist', 'upper_arm'))


def clearances(q: ArrayLike, cell: Cell = Cell(), params: RobotParams = IRB4600
               ) -> tuple[float, float, str]:
    """
    Return the arm's self and scene clearances at ``q`` (m) and the closest pair's name.

    Self: the pairs :data:`SELF_PAIRS` (the tool and wrist folded back onto the upper arm).
    Scene: the forearm, wrist and tool against the pedestal and the camera, and every arm
    capsule against the floor (and the table). The upper arm is left out against the
    pedestal: it is mounted on it (joint 2 is 0.495 m above the base plane).

    Parameters
    ----------
    q : array_like, shape (6,)
        Joint angles (rad).
    cell : Cell
        The cell.
    params : RobotParams
        The robot's geometry.

    Returns
    -------
    tuple of (float, float, str)
        Self clearance, scene clearance (m; negative: overlap) and 'a/b' of the closest
        pair overall.

    """
    arm = {c.name: c for c in arm_capsules(q, params)}
    self_d, scene_d, closest, best = math.inf, math.inf, '', math.inf
    for a, b in SELF_PAIRS:
        d = capsule_distance(arm[a], arm[b])
        self_d = min(self_d, d)
        if d < best:
            best, closest = d, f'{a}/{b}'
    for obj in cell.capsules():
        for name in ('forearm', 'wrist', 'tool'):
            d = capsule_distance(arm[name], obj)
            scene_d = min(scene_d, d)
            if d < best:
                best, closest = d, f'{name}/{obj.name}'
    for plane, height in cell.planes():
        for capsule in arm.values():
            d = plane_distance(capsule, height)
            scene_d = min(scene_d, d)
            if d < best:
                best, closest = d, f'{capsule.name}/{plane}'
    return self_d, scene_d, closest
