"""
``ibvs calibrate``: the camera pose {C} in ``base_link`` from the tool's own spheres.

The maths is :mod:`ibvs_model.handeye`; this module gathers the measurements and writes the result.
Three ways in (docs/real_cell.md, "Hand-eye calibration"):

- the offline simulator (the default): the rendering simulator of ``ibvs run``
  (:class:`ibvs_sim.simulator.Simulator`, its parameters by ``-p``) places the arm at each
  pose, renders the stereo pair with its true camera (``camera_eye``, ``camera_look_at``;
  its image noise), and the detector the feature node runs (:class:`ibvs_vision.detector.
  StereoDetector`, the camera_info's intrinsics) measures the spheres; the encoders read
  q - d_q (``disturbance_deg``). The nominal camera is the one the simulator publishes on
  /stereo/pose: the true one with ``camera_pose_error_xyz_m`` and
  ``camera_pose_error_rpy_deg``. Here the truth is known, and the command says how far the
  result is from it: the rehearsal of a calibration;
- ``--bag DIR``: a recording of a cell (or a rehearsal) while the arm was jogged through
  poses and held still at each, the feature node running: /joint_states (or a run's
  /ibvs/joint_path), /ibvs/features with /ibvs/feature_status (only frames measured, not
  estimated nor blending), the left and right camera_info; one measurement per still pose
  (:func:`ibvs_model.handeye.stations`);
- ``--draw-poses FILE``: only writes the poses to visit (joint angles in degrees, YAML
  ``joints_deg``), drawn in view of the nominal camera, for a cell's operator or for
  ``--poses``.

The result is written as a parameter file holding ``camera_pose`` (``-o``; default
:data:`DEFAULT_OUT`) whose first line is :data:`MARKER`: a file without it is never replaced
unless ``--force`` (:func:`check_output`).
"""

import argparse
import difflib
from pathlib import Path
import sys
from typing import Any

from ibvs_common import contract
from ibvs_common.params import ParameterError
from ibvs_common.shared_params import CAMERA_POSE, camera_pose_from
from ibvs_model import handeye, StereoCamera
import numpy as np
import yaml

#: The first line of every file ``ibvs calibrate`` writes: the mark that lets it replace one.
MARKER = '# written by ibvs calibrate'
#: Where the result goes without ``-o``.
DEFAULT_OUT = Path('results') / 'calibration' / 'camera_pose.yaml'
#: The YAML key of a poses file: joint angles in degrees, one list of six a pose.
POSES_KEY = 'joints_deg'
#: The camera_info topics of either camera_topics setting, by side (a run's or the ZED's).
INFO_SIDES = {contract.LEFT_INFO: 'left', contract.RIGHT_INFO: 'right',
              contract.ZED_LEFT_INFO: 'left', contract.ZED_RIGHT_INFO: 'right'}


class CalibrateError(RuntimeError):
    """A command that cannot be carried out (exit code 2), said in words."""


# ------------------------------------------------------------------------------ files

def check_output(path: str | Path, force: bool = False) -> Path:
    """
    Return ``path`` if ``ibvs calibrate`` may write it; raise :class:`CalibrateError` if not.

    A new file may be written; an existing one only if it starts with :data:`MARKER` (an
    earlier result), or with ``force``. A symbolic link or a folder is refused.
    """
    path = Path(path)
    if path.is_symlink():
        raise CalibrateError(f'{path} is a symbolic link: give the file itself')
    if path.is_dir():
        raise CalibrateError(f'{path} is a folder: give a file name (e.g. '
                             f'{path / DEFAULT_OUT.name})')
    if path.exists() and not force:
        try:
            first = path.read_text(errors='replace').split('\n', 1)[0]
        except OSError as exc:
            raise CalibrateError(f'cannot read {path}: {exc.strerror}') from None
        if first.strip() != MARKER:
            raise CalibrateError(f'{path} exists and ibvs calibrate did not write it (its first '
                                 f"line is not '{MARKER}'): give another file, or --force "
                                 'to replace it')
    return path


def _write(path, text):
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    except OSError as exc:
        raise CalibrateError(f'cannot write {path}: {exc.strerror or exc}') from None
    return path


def parameter_text(calibration: handeye.Calibration, source: str) -> str:
    """Return the parameter file of the result: ``camera_pose`` with what it came from."""
    values = handeye.pose_values(calibration.pose_C_O)
    sp = calibration.sigma_position_m * 1e3
    sr = np.degrees(calibration.sigma_rotation_rad)
    return '\n'.join([
        MARKER,
        f'# the stereo camera {{C}} in base_link, from {len(calibration.used)} poses of '
        f'{source}',
        f'# RMS residual {calibration.rms_px:.4f} px; 1-sigma position '
        f'{sp[0]:.4f}, {sp[1]:.4f}, {sp[2]:.4f} mm, rotation {sr[0]:.5f}, {sr[1]:.5f}, '
        f'{sr[2]:.5f} deg (x, y, z of {{C}})',
        *(['# ' + line for line in handeye.describe(calibration)
           if line.startswith('warning:')]),
        '# ibvs run / ibvs cell: -p camera_pose:=[...] with these values; ros2 run: one more',
        "# --params-file after the cell's",
        '/**:',
        '  ros__parameters:',
        '    camera_pose: [' + ', '.join(f'{v:.9f}' for v in values) + ']',
        ''])


def write_poses(path: str | Path, joints: np.ndarray, note: str, force: bool = False
                ) -> Path:
    """Write the poses (n, 6) rad as a poses file (:data:`POSES_KEY`, degrees)."""
    path = check_output(path, force)
    rows = '\n'.join('- [' + ', '.join(f'{v:.6f}' for v in np.degrees(q)) + ']'
                     for q in joints)
    return _write(path, f'{MARKER}\n# {note}\n{POSES_KEY}:\n{rows}\n')


def read_poses(path: str | Path) -> np.ndarray:
    """Return the poses (n, 6) rad of a poses file; :class:`CalibrateError` if it is not one."""
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise CalibrateError(f'cannot read the poses file {path}: {exc.strerror}') from None
    except yaml.YAMLError as exc:
        raise CalibrateError(f'{path} is not YAML: {exc}') from None
    rows = data.get(POSES_KEY) if isinstance(data, dict) else None
    try:
        joints = np.radians(np.array(rows, dtype=float))
    except (TypeError, ValueError):
        joints = None
    if joints is None or joints.ndim != 2 or joints.shape[1] != 6 or \
            not np.all(np.isfinite(joints)):
        raise CalibrateError(f"{path}: expected '{POSES_KEY}:' with a list of poses, each six "
                             'joint angles in degrees')
    return joints


# ------------------------------------------------------------------ the measurements

def sim_config(overrides: dict[str, Any]):
    """
    Return the simulator's config of the ``-p`` values and the nominal camera pose, if given.

    Names: the simulator's parameters (:class:`ibvs_sim.node_params.SimConfig`) and
    ``camera_pose``; another name is refused with the nearest ones.
    """
    from ibvs_sim.node_params import SimConfig
    names = {p.name for p in SimConfig.params()}
    values = dict(overrides)
    nominal = None
    if CAMERA_POSE.name in values:
        try:
            nominal = camera_pose_from({CAMERA_POSE.name: CAMERA_POSE.check(
                values.pop(CAMERA_POSE.name))})
        except ParameterError as exc:
            raise CalibrateError(str(exc)) from None
    for name in values:
        if name not in names:
            near = difflib.get_close_matches(name, sorted(names | {CAMERA_POSE.name}), n=3)
            hint = f"; did you mean {', '.join(repr(n) for n in near)}?" if near else ''
            raise CalibrateError(f"-p '{name}': not a parameter of the simulator or "
                                 f'camera_pose{hint}')
    try:
        return SimConfig.make(**values), nominal
    except ParameterError as exc:
        raise CalibrateError(str(exc)) from None


def simulator(config, render: bool = True):
    """Return the :class:`ibvs_sim.simulator.Simulator` of ``config`` (refusals in words)."""
    from ibvs_sim.simulator import Simulator
    try:
        return Simulator(config, render=render)
    except ParameterError as exc:
        raise CalibrateError(str(exc)) from None


def simulate(sim, joints: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """
    Measure the poses in the simulator: (encoder joints (m, 6), features (m, 6), failures).

    For each pose q (the encoders' angles): the true joints q + d_q set, the stereo pair
    rendered with the simulator's true camera, supersampling and image noise, and detected
    as the feature node does on a whole pair, with the intrinsics the simulator publishes.
    ``failures``: one line per pose the detector did not measure.
    """
    from ibvs_vision.detector import StereoDetector
    detector = StereoDetector(sim.calibrated_camera.intrinsics)
    got_q, got_p, failures = [], [], []
    for i, q in enumerate(joints):
        sim.world.reset(q + sim.d_q)
        images = sim.effects.noisy(sim.world.render_stereo(
            sim.camera, sim.render_supersampling, sim.world.marker_spheres(),
            sim.render_marker_supersampling))
        detection = detector.detect(*images)
        if detection.ok:
            got_q.append(q)
            got_p.append(detection.features)
        else:
            failures.append(f'pose {i}: not measured ({detection.reason.value}: '
                            f'{detection.detail})')
    return np.array(got_q).reshape(-1, 6), np.array(got_p).reshape(-1, 6), failures


def _stamp_ns(header):
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def read_bag(bag: str | Path) -> dict[str, Any]:
    """
    Return what a recording holds for a calibration.

    Keys: ``frame_t`` (s) and ``features`` (f, 6) of the frames the feature node measured
    (its /ibvs/feature_status of the same stamp says mode and reason 'measured'),
    ``frames`` (all the /ibvs/features), ``joint_t``, ``joints`` (the arm's joints of each
    /joint_states by name, other joints ignored; a run's bag without them: its
    /ibvs/joint_path, :func:`ibvs_analysis.analysis.load_joints`), ``intrinsics`` (from the
    first left and right camera_info), ``nominal`` (4x4 or None: the recorded ``camera_pose``
    parameter, else the first /stereo/pose). A message that cannot be read is skipped.
    """
    from ibvs_analysis import analysis
    from ibvs_common.conversions import (InputError, intrinsics_from_infos, pose_matrix,
                                         read_feature_status, read_features, read_joints)
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import get_typestore, Stores
    bag = Path(bag)
    if not (bag / 'metadata.yaml').is_file():
        raise CalibrateError(f'no bag at {bag} (a folder with metadata.yaml)')
    features, measured, infos, pose, states = {}, set(), {}, None, []
    params = {}
    try:
        meta = yaml.safe_load((bag / 'metadata.yaml').read_text()) or {}
        custom = meta.get('rosbag2_bagfile_information', {}).get('custom_data') or {}
        params = yaml.safe_load(custom.get(analysis.PARAMS_KEY, '{}')) or {}
        with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
            wanted = {contract.FEATURES, contract.FEATURE_STATUS, contract.STEREO_POSE,
                      contract.JOINT_STATES, *INFO_SIDES}
            conns = [c for c in reader.connections if c.topic in wanted]
            for conn, _, raw in reader.messages(connections=conns):
                msg = reader.deserialize(raw, conn.msgtype)
                try:
                    if conn.topic == contract.FEATURES:
                        features[_stamp_ns(msg.header)] = read_features(msg)
                    elif conn.topic == contract.FEATURE_STATUS:
                        status = read_feature_status(msg)
                        if status.measured and status.mode == contract.FEATURE_MEASURED:
                            measured.add(_stamp_ns(msg.header))
                    elif conn.topic == contract.JOINT_STATES:  # by name, in any order
                        states.append((_stamp_ns(msg.header), read_joints(msg)))
                    elif conn.topic in INFO_SIDES:
                        infos.setdefault(INFO_SIDES[conn.topic], msg)
                    elif pose is None:
                        pose = pose_matrix(msg.pose)
                except InputError:
                    continue  # a bad message is no measurement
        if states:
            states.sort(key=lambda s: s[0])
            joint_t = np.array([t * 1e-9 for t, _ in states])
            joints = np.array([q for _, q in states])
        else:  # a run's bag: the simulator's batches
            joint_t, joints = analysis.load_joints(bag)[:2]
    except Exception as exc:  # noqa: B902 (rosbags' and the file system's own errors)
        raise CalibrateError(f'cannot read the bag {bag}: {type(exc).__name__}: {exc}') \
            from None
    if len(infos) < 2:
        raise CalibrateError(f'{bag} holds no left and right camera_info '
                             f'({", ".join(sorted(INFO_SIDES))}): the intrinsics are needed')
    try:
        intrinsics = intrinsics_from_infos(infos['left'], infos['right'])
    except InputError as exc:
        raise CalibrateError(f'{bag}: the camera_info is unusable: {exc}') from None
    nominal = None
    try:
        nominal = camera_pose_from(params) if CAMERA_POSE.name in params else None
    except ParameterError:
        nominal = None
    if nominal is None:
        nominal = pose
    stamps = sorted(s for s in features if s in measured)
    return {'frame_t': np.array([s * 1e-9 for s in stamps]),
            'features': np.array([features[s] for s in stamps]).reshape(-1, 6),
            'frames': len(features), 'joint_t': joint_t, 'joints': joints,
            'intrinsics': intrinsics, 'nominal': nominal}


# ------------------------------------------------------------------------- the command

def _difference_line(what, reference, pose):
    shift, angle = handeye.pose_difference(reference, pose)
    return (f'  {what}: {np.linalg.norm(shift) * 1e3:.4f} mm ('
            + ', '.join(f'{v * 1e3:.4f}' for v in shift) + f' mm along x, y, z), '
            f'{angle:.5f} deg')


def _parse_overrides(texts):
    from ibvs_bringup import scenario
    try:
        return dict(scenario.parse_override(t) for t in texts)
    except scenario.ScenarioError as exc:
        raise CalibrateError(str(exc)) from None


def _from_simulator(args, overrides, out):
    config, nominal = sim_config(overrides)
    sim = simulator(config, render=not args.draw_poses)
    try:
        if nominal is None:
            nominal = sim.calibrated_camera.pose_C_O
        camera = StereoCamera(sim.calibrated_camera.intrinsics, nominal)
        if args.poses:
            joints = read_poses(args.poses)
            drawn = f'the poses file {args.poses}'
        else:
            joints = handeye.draw_poses(camera, args.count, args.seed, sim.params)
            drawn = f'{args.count} poses drawn with seed {args.seed}'
        if args.draw_poses:
            path = write_poses(args.draw_poses, joints, f'{drawn}, both spheres in view of '
                               'the camera at ' + str([round(v, 6) for v in
                                                       handeye.pose_values(nominal)]),
                               args.force)
            print(f'wrote {len(joints)} poses to {path}')
            return 0
        print(f'calibrating in the offline simulator: {drawn}')
        q, p, failures = simulate(sim, joints)
        for line in failures:
            print(f'  {line}')
        result = handeye.solve(sim.calibrated_camera.intrinsics, q, p, sim.params)
        truth = sim.camera.pose_C_O
    finally:
        sim.close()
    _report(result)
    print(_difference_line('correction to the nominal camera (/stereo/pose)', nominal,
                           result.pose_C_O))
    print(_difference_line('error against the true camera', truth, result.pose_C_O))
    return _finish(result, out, 'the offline simulator', args.force)


def _from_bag(args, overrides, out):
    if set(overrides) - {CAMERA_POSE.name}:
        raise CalibrateError('with --bag, -p takes camera_pose only (the nominal camera to '
                             'compare with)')
    data = read_bag(args.bag)
    nominal = data['nominal']
    if CAMERA_POSE.name in overrides:
        nominal = sim_config({CAMERA_POSE.name: overrides[CAMERA_POSE.name]})[1]
    found = handeye.stations(data['frame_t'], data['features'], data['joint_t'],
                             data['joints'], still_tol_rad=np.radians(args.still_tol_deg))
    print(f"{args.bag}: {data['frames']} feature frames, {len(data['frame_t'])} measured, "
          f"{len(data['joint_t'])} joint states: {len(found.frames)} still poses")
    for i, (t, n, spread) in enumerate(zip(found.start_s, found.frames, found.spread_px)):
        print(f'  pose {i}: from t = {t:.3f} s, {n} frames, spread {spread:.4f} px')
    if len(found.frames) < handeye.MIN_POSES:
        raise CalibrateError(
            f'{len(found.frames)} still poses in {args.bag} (at least {handeye.MIN_POSES} '
            f'needed): hold the arm still at each pose for a second or more, the spheres '
            f'measured (feature_status measured), every joint within {args.still_tol_deg:g} '
            'deg (--still-tol-deg)')
    result = handeye.solve(data['intrinsics'], found.joints, found.features)
    _report(result)
    if nominal is not None:
        print(_difference_line('correction to the nominal camera', nominal, result.pose_C_O))
    return _finish(result, out, f'the bag {args.bag}', args.force)


def _report(result):
    """Print the result (:func:`ibvs_model.handeye.describe`), a warning on stderr."""
    for line in handeye.describe(result):
        print(line, file=sys.stderr if line.startswith('warning:') else sys.stdout)


def _finish(result, out, source, force):
    path = _write(check_output(out, force), parameter_text(result, source))
    values = ','.join(f'{v:.9f}' for v in handeye.pose_values(result.pose_C_O))
    print(f'wrote {path}')
    print(f'  -p camera_pose:=[{values}]')
    return 0


def main(args: argparse.Namespace) -> int:
    """Run ``ibvs calibrate`` (:mod:`.cli` parses its arguments); return the exit code."""
    try:
        overrides = _parse_overrides(args.param)
        if args.bag and (args.poses or args.draw_poses):
            raise CalibrateError('--bag takes the poses the recording holds: not with '
                                 '--poses or --draw-poses')
        if args.count < handeye.MIN_POSES:
            raise CalibrateError(f'-n {args.count}: a calibration needs at least '
                                 f'{handeye.MIN_POSES} poses')
        out = Path(args.out or DEFAULT_OUT)
        if not args.draw_poses:
            check_output(out, args.force)  # before any work
        if args.bag:
            return _from_bag(args, overrides, out)
        return _from_simulator(args, overrides, out)
    except (CalibrateError, handeye.CalibrationError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
