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
from ibvs_common import contract
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


def load_parameters(name_or_path: str | Path) -> dict[str, Any]:
    """Return the ``/**`` parameters of a scenario file as a dict."""
    path = scenario_path(name_or_path)
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except yaml.YAMLError as exc:
        raise ScenarioError(f'{path}: not valid YAML: {exc}') from None
    try:
        params = dict(data['/**']['ros__parameters'])
    except (KeyError, TypeError):
        raise ScenarioError(f"{path}: expected '/**: ros__parameters: {{...}}'") from None
    return params


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
    """Parse 'name:=value' (value in YAML syntax, as ``ros2 run ... -p`` takes it)."""
    if ':=' not in text:
        raise ScenarioError(f'override {text!r} is not of the form name:=value')
    name, value = text.split(':=', 1)
    try:
        return name.strip(), yaml.safe_load(value)
    except yaml.YAMLError as exc:
        raise ScenarioError(f'override {text!r}: the value is not valid YAML: {exc}') from None


def write_parameters(params: Mapping[str, Any], path: str | Path) -> Path:
    """Write ``params`` as a ``/**`` parameter file at ``path`` and return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump({'/**': {'ros__parameters': params}}, sort_keys=True))
    return path
