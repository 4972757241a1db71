"""
Scenario parameter files: find them, read them, override values, write the file nodes get.

A scenario file is a ROS 2 parameter file whose parameters sit under ``/**`` so that every
node started with ``--ros-args --params-file <file>`` sees them.
"""

from collections.abc import Mapping
import importlib.util
from pathlib import Path
from typing import Any

from ament_index_python.packages import get_package_share_directory, PackageNotFoundError
from ibvs_common import contract, ros_args
import yaml

SCENARIOS = ('scenario1', 'scenario2', 'scenario3')
#: Keys of a run's parameters that only the runner reads and no node declares: the run's
#: name and its sim time limit.
RUNNER_KEYS = ('scenario_name', 'run_duration_s')
#: What the runner keeps from the nodes: its own keys, and sim_node's ``duration_s`` (the
#: runner stops the run at its limit itself; a node started by hand may use it).
RUNNER_ONLY = RUNNER_KEYS + ('duration_s',)


class ScenarioError(ValueError):
    """A scenario cannot be found or its file is malformed."""


def share_directory(package: str = 'ibvs_bringup') -> Path:
    """Return the installed share directory of ``package`` (its source tree if not built)."""
    try:
        return Path(get_package_share_directory(package))
    except (PackageNotFoundError, OSError):  # not installed: the source tree
        return Path(importlib.util.find_spec(package).origin).resolve().parents[1]


def scenario_path(name_or_path: str | Path) -> Path:
    """Return the parameter file of a scenario name ('scenario1') or an explicit path."""
    path = Path(name_or_path)
    if path.suffix in ('.yaml', '.yml'):
        if not path.is_file():
            raise ScenarioError(f'scenario file {path} does not exist')
        return path
    share = share_directory()
    candidate = share / 'config' / f'{name_or_path}.yaml'
    if not candidate.is_file():
        known = sorted(p.stem for p in (share / 'config').glob('*.yaml'))
        raise ScenarioError(f'unknown scenario {name_or_path!r}; known: {known}')
    return candidate


def load_parameters(name_or_path: str | Path, what: str = 'scenario file') -> dict[str, Any]:
    """
    Return the ``/**`` parameters of a scenario file as a dict, each value as rcl reads it.

    The values are typed as a node's rcl types them (:func:`ibvs_common.ros_args.scalar`:
    ``1e-300`` a double, ``1:2`` a string), not as PyYAML would. ``what`` names the file in
    a refusal (``parameter file`` for ``ibvs cell --params-file``).
    """
    path = Path(name_or_path)
    if what != 'scenario file' and not path.is_file():
        raise ScenarioError(f'{what} {path} does not exist')
    path = scenario_path(name_or_path)
    try:
        sections = dict(ros_args.file_sections(path))
    except ros_args.ArgumentsError as exc:
        text = str(exc).replace('parameter file', what, 1)
        raise ScenarioError(text if 'expected' not in text else
                            f"{path}: expected '/**: ros__parameters: {{...}}'") from None
    if '/**' not in sections:
        raise ScenarioError(f"{path}: expected '/**: ros__parameters: {{...}}'")
    params = {}
    for name, value in sections['/**']:
        if value is ros_args.UNTYPED:
            raise ScenarioError(f"{path}: parameter '{name}': rcl takes a scalar or an array "
                                'of scalars of one type')
        params[name] = value
    return params


def check_clock(params: Mapping[str, Any], simulated: bool) -> None:
    """
    Refuse a ``use_sim_time`` that contradicts where time comes from.

    ``simulated``: a graph with the simulator (``ibvs run``), which owns time and publishes
    /clock: every node must run on it (``use_sim_time: true``), or the lockstep's stamps and
    the nodes' clocks disagree from the first step. ``ibvs cell`` does not call it: on a cell
    its nodes run on the wall clock (``cell.yaml``), and ``-p use_sim_time:=true`` is the
    rehearsal against a ``sim_node`` started by hand (docs/real_cell.md), whose /clock a
    stopped-clock hold watches (ibvs_control.servo_status).
    """
    if 'use_sim_time' not in params:
        return
    value = params['use_sim_time']
    if value is not simulated:
        why = ('the simulator owns time and publishes /clock: every node runs on it'
               if simulated else
               'a real cell has no simulator and no /clock: a node on sim time would wait '
               'for it forever')
        raise ScenarioError(f"parameter 'use_sim_time' = {value!r} is invalid: it must be "
                            f'{str(simulated).lower()} here ({why})')


def check_progress(params: Mapping[str, Any]) -> None:
    """
    Refuse a configuration with which the graph of ``ibvs run`` cannot advance sim time.

    The joint controller answers /joint_states at t only once it has /ibvs/q_feedback of the
    frame that applies at t (DESIGN section 4), and that comes from the feature node, which
    needs both stereo images of the frame. Without images (``publish_images: false``) the run
    would wait at the first frame forever; it is refused here, before any node starts.
    """
    if params.get('publish_images', True) is False:
        raise ScenarioError(
            f'publish_images is false: the feature node would get no {contract.LEFT_IMAGE} '
            f'or {contract.RIGHT_IMAGE}, hence no {contract.FEATURES}, and the joint '
            f'controller would wait for {contract.Q_FEEDBACK} of the first camera frame '
            'forever; the node graph needs the images (publish_images:=false is for the '
            'simulator on its own)')


def parse_override(text: str) -> tuple[str, Any]:
    """
    Parse 'name:=value', the value typed as rcl types a ``ros2 run ... -p`` value.

    :func:`ibvs_common.ros_args.parse_rule`: ``1e-300`` is a double, ``1:2`` and ``~``
    strings, ``0x10`` 16, as a node started with that ``-p`` would read them; an array
    may mix integers and doubles (all doubles then, as the run's parameter file needs).
    """
    if ':=' not in text:
        raise ScenarioError(f'override {text!r} is not of the form name:=value')
    rule = ros_args.parse_rule(text, mixed=True)
    if rule is None or rule[0] != '/**':
        raise ScenarioError(f'override {text!r}: rcl would refuse it (no value, a value '
                            'that is not YAML, or a node name before the parameter)')
    name, value = rule[1].strip(), rule[2]
    if isinstance(value, list) and any(isinstance(v, float) for v in value) and \
            all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        value = [float(v) for v in value]  # [0.1, 0]: doubles, as rcl needs them in a file
    if value is ros_args.UNTYPED:
        raise ScenarioError(f'override {text!r}: rcl takes a scalar or an array of scalars '
                            'of one type')
    return name, value


def write_parameters(params: Mapping[str, Any], path: str | Path) -> Path:
    """Write ``params`` as a ``/**`` parameter file at ``path`` and return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump({'/**': {'ros__parameters': params}}, sort_keys=True))
    return path
