"""
Seeded tasks across the workspace: a start and a target the camera sees, as data.

A *task* is a start (``start_joints``, true joint angles, rad) and a target (the flange
pose: ``target_position`` in {O}, m, and ``target_rotation``, row-major 3x3), the three
node parameters of those names. :func:`tasks` draws them (pure numpy, seeded): task k of
``tasks(n, seed)`` is the same for every n > k (rejection sampling in one stream).

A target is kept when (each a margin below, :class:`Margins`):

- the inverse kinematics reaches it with every joint ``joint_margin_rad`` inside its limits
  (:attr:`ibvs_model.robot.RobotParams.q_min`, ``q_max``);
- both markers are in view of both lenses: each marker's disc (radius
  :data:`.scene.MARKER_RADIUS_M` at its depth) ``image_margin_px`` inside both images, at
  least ``min_depth_m`` deep, and the two discs apart by their radii and
  ``marker_gap_px`` (:func:`.scene.discs_apart`), and neither lens sees P1 from within
  ``wrist_clear_deg`` of straight behind the wrist (:func:`.scene.wrist_clear`);
- the flange and both markers are ``pedestal_clearance_m`` clear of the pedestal (the
  robot's base: a vertical cylinder of radius ``pedestal_radius_m`` about the z axis of {O}
  from the floor to the shoulder), ``floor_clearance_m`` above the floor (``z =
  -mount_height_m``: the simulator's riser, 0.5 m by default; the simulated cell has no
  table, so the floor is the surface under the tool) and ``camera_clearance_m`` from the
  camera's optical centre;
- the arm is away from its singularities: the condition number of its geometric Jacobian
  (:func:`.robot.condition_number`) is below ``max_condition_number``, MoveIt Servo's
  ``lower_singularity_threshold`` (17), where the safety envelope starts to slow a law down
  (``ibvs_control.envelope``): a target inside that band is one no law may approach at speed;
- the tool axis is observable to the success criterion: :func:`axis_observability` at
  least ``min_observability_px_rad``. A target taught on one frame is one detection, so its
  features carry the detector's noise sigma (0.0076 px per feature at HD720, measured:
  ``ibvs vsbench --measure-noise --resolution HD720``) and the worst tilt of the taught
  axis has a standard deviation of sigma / observability rad. Three of them within the
  success criterion's 0.5 deg: observability >= 3 x 0.0076 / radians(0.5) = 2.6 px/rad. A
  weaker target is a test of the camera, not of a servo law: no law can end within 0.5 deg
  of a target the camera places 0.5 deg off. (workspace-1 kept them: 37 % of its 500. The
  benchmark teaches on 10 frames since, sigma / sqrt(10); the margin stays the one-frame
  one, so that a task set holds for a teach of any length.)

**workspace-3** keeps what workspace-2 keeps, with two changes. The observability bound
follows from the teach the benchmark uses, not from one frame: :func:`observability_bound`
of ``teach_frames`` (10: 0.83 px/rad instead of 2.6), which brings back the third of the
workspace workspace-2 refuses and which a ten-frame teach serves within the criterion. And
every target must pass a line-of-sight check the caller gives (``line_of_sight``: the
markers seen by both lenses past the arm's own links and the cell). The margins above are
geometric and say nothing of what hides a marker: at 6 of workspace-2's first 500 targets
of seed 1 (165, 193, 203, 224, 238, 253) the forearm hides them or the detector finds
none. ``ibvs_experiments.line_of_sight`` renders the target as the simulator does and runs
the detector (exact where the capsules of :mod:`.capsules`, conservative by design, would
also refuse targets the camera sees); this package stays without a renderer.

A start is the target's joint angles plus a uniform offset of up to ``start_offset_rad``
per joint (joint 6 too: its roll is unobservable and the loop never corrects it), kept when
within the limits by the same margin and clear of the pedestal and the floor; it need not
be in view (the feature node's estimates carry the loop until the markers are seen).

Each task carries its tool-axis observability (:func:`axis_observability`) and its
condition number, the measures its target passed, for the study's tables.

``python -m ibvs_experiments.tasks`` writes a task set to JSON or CSV.
"""

from collections import Counter
from collections.abc import Callable
from dataclasses import asdict, dataclass
import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

# default_model: the package's (the paper's robot, the ZED 2 at the paper's pose).
from . import default_model
from .combined import CameraRobotModel
from .errors import ModelError
from .robot import condition_number, fiducial_points, forward_kinematics, ik_position_axis
from .scene import discs_apart, MARKER_RADIUS_M, wrist_clear, WRIST_CLEAR_DEG

#: The version of the task set: a task set is (VERSION, n, seed). Change it with anything
#: that changes which tasks a seed draws (the bounds, margins, camera or the draw order).
#: workspace-2: targets below the singularity slow-down threshold and observable to the
#: success criterion (module docstring); :func:`.scene.wrist_clear` with the lenses at
#: -b/2 and +b/2 (workspace-1 put them at 0 and b).
VERSION = 'workspace-2'
#: The versions :func:`tasks` draws; workspace-3 needs a ``line_of_sight`` check (module
#: docstring).
VERSIONS = (VERSION, 'workspace-3')
#: The detector's noise per feature on one frame at HD720 (px; ``ibvs vsbench
#: --measure-noise --resolution HD720``) and the success criterion's tool-axis bound (deg):
#: what :func:`observability_bound` is made of.
TEACH_NOISE_PX = 0.0076
SUCCESS_AXIS_DEG = 0.5


@dataclass(frozen=True)
class Margins:
    """The margins a task keeps (module docstring); the defaults are those of VERSION."""

    joint_margin_rad: float = math.radians(5.0)
    image_margin_px: float = 10.0
    min_depth_m: float = 1.0
    marker_gap_px: float = 1.0
    wrist_clear_deg: float = WRIST_CLEAR_DEG
    pedestal_radius_m: float = 0.45
    pedestal_top_m: float = 0.6
    pedestal_clearance_m: float = 0.2
    mount_height_m: float = 0.5
    floor_clearance_m: float = 0.15
    camera_clearance_m: float = 0.5
    max_tilt_deg: float = 35.0
    start_offset_rad: float = math.radians(20.0)
    max_condition_number: float = 17.0
    min_observability_px_rad: float = 2.6


def observability_bound(teach_frames: int = 1, noise_px: float = TEACH_NOISE_PX) -> float:
    """
    Return the least tool-axis observability (px/rad) a target taught on ``teach_frames``.

    The taught features' noise is noise_px / sqrt(teach_frames), and the taught axis tilts
    by that over the observability (rad, standard deviation): three of them within the
    success criterion's 0.5 deg, 3 noise_px / sqrt(teach_frames) / radians(0.5) (one frame:
    2.6 px/rad, workspace-2's margin; ten: 0.83).
    """
    if teach_frames < 1:
        raise ValueError(f'teach_frames must be >= 1, got {teach_frames!r}')
    return 3.0 * noise_px / math.sqrt(teach_frames) / math.radians(SUCCESS_AXIS_DEG)


#: Where targets are drawn: the flange in this box of {O} (m), in front of the camera.
TARGET_BOX_M = ((-1.4, -0.4, 0.0), (1.4, 0.5, 1.2))


def axis_observability(model: CameraRobotModel, q: ArrayLike) -> float:
    """
    Return the tool-axis observability at ``q``: px of feature motion per rad of tilt, worst.

    The six features depend on the two markers only: p = (pi(P1), pi(P2)). Tilting the tool
    axis about P1 by a small angle theta about a unit w perpendicular to the axis moves P2
    by theta w x (P2 - P1) and P1 not at all: two columns d p / d theta (px/rad). A tilt that
    a flange translation would mimic is not seen as a tilt, so each column is projected on
    the orthogonal complement of the three columns d p / d P1 (px/m; a translation of the
    whole tool). The smallest singular value of the two projected columns is the result:
    the feature motion of the worst tilt that no translation explains. This is the chain
    rule of :meth:`.combined.CameraRobotModel.jacobian` (C1 = dp/dP dP/dq) taken with P
    (the flange position and the tool axis) instead of q as the variables, so the arm's own
    singularities do not enter; those the joint margins and the IK keep away from.

    Parameters
    ----------
    model : CameraRobotModel
        The robot and the camera.
    q : array_like, shape (6,)
        Joint angles (rad).

    Returns
    -------
    float
        px / rad.

    """
    p1, p2 = fiducial_points(q, model.params)
    j1 = model.camera.projection_jacobian(p1)
    j2 = model.camera.projection_jacobian(p2)
    translation = np.vstack([j1, j2])  # (6, 3): the whole tool moved by dP1
    axis = (p2 - p1) / np.linalg.norm(p2 - p1)
    w1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    w1 /= np.linalg.norm(w1)
    w2 = np.cross(axis, w1)
    tilt = np.column_stack([np.concatenate([np.zeros(3), j2 @ np.cross(w, p2 - p1)])
                            for w in (w1, w2)])
    basis, _ = np.linalg.qr(translation)
    tilt -= basis @ (basis.T @ tilt)
    return float(np.linalg.svd(tilt, compute_uv=False).min())


def _limits(params, margin):
    return np.asarray(params.q_min) + margin, np.asarray(params.q_max) - margin


def _clear_of_cell(points, margins):
    """Return whether ``points`` (N, 3) in {O} are clear of the pedestal and the floor."""
    radial = np.hypot(points[:, 0], points[:, 1])
    near_pedestal = (radial < margins.pedestal_radius_m + margins.pedestal_clearance_m) & \
        (points[:, 2] < margins.pedestal_top_m + margins.pedestal_clearance_m)
    above_floor = points[:, 2] > -margins.mount_height_m + margins.floor_clearance_m
    return bool(not near_pedestal.any() and above_floor.all())


def target_check(model: CameraRobotModel, q: ArrayLike, margins: Margins = Margins(),
                 measures: dict[str, float] | None = None) -> str | None:
    """
    Return why ``q`` is no target under ``margins`` (module docstring), or None.

    ``measures``: filled with the ``condition_number`` and ``observability`` of ``q`` as
    they are computed (a task keeps them, :func:`tasks`).
    """
    measures = {} if measures is None else measures
    q = np.asarray(q, dtype=float)
    lo, hi = _limits(model.params, margins.joint_margin_rad)
    if np.any(q < lo) or np.any(q > hi):
        return 'a joint within the margin of its limit'
    points = fiducial_points(q, model.params)
    flange = forward_kinematics(q, model.params)[:3, 3]
    if not _clear_of_cell(np.vstack([points, flange]), margins):
        return 'too close to the pedestal or the floor'
    centre = model.camera.to_base(np.zeros((1, 3)))[0]
    if np.linalg.norm(points - centre, axis=1).min() < margins.camera_clearance_m:
        return 'too close to the camera'
    depth = model.camera.to_camera(points)[:, 2]
    if depth.min() < margins.min_depth_m:
        return 'a marker nearer than min_depth_m'
    radius_px = model.camera.intrinsics.fu * MARKER_RADIUS_M / depth.min()
    if not np.all(model.camera.in_view(points, margin_px=radius_px + margins.image_margin_px)):
        return 'a marker out of view (with the margin)'
    if not discs_apart(model.camera, points, margins.marker_gap_px):
        return 'the markers overlap in an image'
    if not wrist_clear(model.camera, points, margins.wrist_clear_deg):
        return 'a lens looks at P1 from behind the wrist'
    measures['condition_number'] = condition_number(q, model.params)
    if measures['condition_number'] >= margins.max_condition_number:
        return 'the arm near a singularity (condition number)'
    measures['observability'] = axis_observability(model, q)
    if measures['observability'] < margins.min_observability_px_rad:
        return 'the tool axis weakly observable'
    return None


def start_check(model: CameraRobotModel, q: ArrayLike, margins: Margins = Margins()
                ) -> str | None:
    """Return why ``q`` is no start (limits, pedestal, floor; view not needed), or None."""
    q = np.asarray(q, dtype=float)
    lo, hi = _limits(model.params, margins.joint_margin_rad)
    if np.any(q < lo) or np.any(q > hi):
        return 'a joint within the margin of its limit'
    points = np.vstack([fiducial_points(q, model.params),
                        forward_kinematics(q, model.params)[:3, 3]])
    if not _clear_of_cell(points, margins):
        return 'too close to the pedestal or the floor'
    return None


def _task_dict(model, index, seed, q_start, q_target, measures, version=VERSION):
    pose = forward_kinematics(q_target, model.params)
    return {
        'id': f'{version}/{seed}/{index}',
        'version': version,
        'seed': int(seed),
        'index': int(index),
        'start_joints': [float(v) for v in q_start],
        'target_position': [float(v) for v in pose[:3, 3]],
        'target_rotation': [float(v) for v in pose[:3, :3].reshape(9)],
        'target_joints': [float(v) for v in q_target],
        'observability': measures['observability'],
        # For comparison: the joint-space measure, the 5th singular value of C1 (its 6th is
        # 0: joint 6 moves no feature); it mixes the tilt with the arm's joint scaling.
        'jacobian_sigma5': float(np.linalg.svd(model.jacobian(q_target),
                                               compute_uv=False)[4]),
        'condition_number': measures['condition_number'],
    }


def tasks(n: int, seed: int, model: CameraRobotModel | None = None,
          margins: Margins | None = None, max_tries: int = 200000,
          tally: 'Counter[str] | None' = None, version: str = VERSION,
          line_of_sight: 'Callable[[NDArray[np.float64]], str | None] | None' = None,
          teach_frames: int = 10) -> list[dict[str, Any]]:
    """
    Return ``n`` tasks drawn with ``numpy.random.default_rng(seed)`` (module docstring).

    Parameters
    ----------
    n : int
        How many tasks (>= 0).
    seed : int
        The seed (>= 0).
    model : CameraRobotModel, optional
        The robot and camera; default :func:`default_model` (the paper's cell at HD720).
    margins : Margins, optional
        The margins kept; default workspace-2's (:class:`Margins`), and for workspace-3
        the same with the observability bound of ``teach_frames``.
    max_tries : int
        Draws before giving up (a RuntimeError: the margins leave no room).
    tally : collections.Counter, optional
        Filled with why draws were refused (the reasons of :func:`target_check` and
        :func:`start_check`, 'unreachable' where the IK has no solution) and 'kept'.
    version : str
        One of :data:`VERSIONS`.
    line_of_sight : callable, optional
        workspace-3 only, and needed there: why the markers are not seen at a target's
        joint angles, or None (called last, on a target and start that passed the rest).
    teach_frames : int
        workspace-3: the frames the target is taught on, which set the observability
        bound (:func:`observability_bound`).

    Returns
    -------
    list of dict
        Per task: ``id`` ('<VERSION>/<seed>/<k>'), ``version``, ``seed``, ``index``, the
        node parameters ``start_joints`` (6, rad), ``target_position`` (3, m),
        ``target_rotation`` (9, row-major), and ``target_joints`` (6, rad: the IK branch
        found), ``observability`` (px/rad, :func:`axis_observability`),
        ``jacobian_sigma5`` (px/rad, the 5th singular value of C1 at the target) and
        ``condition_number`` (:func:`.robot.condition_number` at the target).

    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
        raise ValueError(f'n: expected an integer >= 0, got {n!r}')
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f'seed: expected an integer >= 0, got {seed!r}')
    if version not in VERSIONS:
        raise ValueError(f'version must be one of {VERSIONS}, got {version!r}')
    if (version == VERSION) != (line_of_sight is None):
        raise ValueError(f'{VERSIONS[1]} needs a line_of_sight check and {VERSION} takes '
                         f'none (version {version!r})')
    if margins is None:
        margins = margins_for(version, teach_frames)
    model = default_model() if model is None else model
    rng = np.random.default_rng(seed)
    tally = Counter() if tally is None else tally
    out = []
    tries = 0
    while len(out) < n:
        tries += 1
        if tries > max_tries:
            raise RuntimeError(f'{len(out)} of {n} tasks after {max_tries} draws: the '
                               'margins leave (almost) no room')
        position = rng.uniform(*TARGET_BOX_M)
        tilt = math.radians(rng.uniform(0.0, margins.max_tilt_deg))
        azimuth = rng.uniform(0.0, 2.0 * math.pi)
        q6 = rng.uniform(-math.pi, math.pi)
        offset = rng.uniform(-margins.start_offset_rad, margins.start_offset_rad, 6)
        axis = [math.sin(tilt) * math.cos(azimuth), math.sin(tilt) * math.sin(azimuth),
                -math.cos(tilt)]
        try:
            q = ik_position_axis(position, axis, q6, model.params)
        except ModelError:
            tally['unreachable'] += 1
            continue
        measures = {}
        why = target_check(model, q, margins, measures)
        if why is not None:
            tally[f'target: {why}'] += 1
            continue
        q_start = q + offset
        why = start_check(model, q_start, margins)
        if why is not None:
            tally[f'start: {why}'] += 1
            continue
        why = None if line_of_sight is None else line_of_sight(q)
        if why is not None:
            tally[f'target: markers not seen ({why})'] += 1
            continue
        tally['kept'] += 1
        out.append(_task_dict(model, len(out), seed, q_start, q, measures, version))
    return out


def margins_for(version: str = VERSION, teach_frames: int = 1) -> Margins:
    """Return a version's default margins: workspace-3's observability bound of the teach."""
    if version == VERSION:
        return Margins()
    return Margins(min_observability_px_rad=observability_bound(teach_frames))


def describe(margins: Margins = Margins(), version: str = VERSION) -> dict[str, Any]:
    """Return the task set's definition (version, box, margins) for a task file's header."""
    return {'version': version, 'target_box_m': [list(b) for b in TARGET_BOX_M],
            'margins': asdict(margins)}
