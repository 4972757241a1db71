"""
Each shipped parameter file starts its nodes without a warning about its own settings.

A node that is given a setting it does not use says so at start (the joint controller in
position mode names the effort interface's parameters set off their defaults; the
simulator in lockstep names the free-running ones, free-running the frame joint states):
a file the project ships must not set what its own nodes then call ignored. The nodes'
checks are run on each file's values without starting a node.
"""

from pathlib import Path

from ibvs_common.params import RETIRED
from ibvs_control.node_params import JointControllerConfig
from ibvs_control.position_controller import EFFORT_ONLY, PositionController
from ibvs_sim.lockstep_sim import FREE_RUNNING_ONLY
from ibvs_sim.node_params import SimNodeConfig
import pytest
import yaml

CONFIG = Path(__file__).resolve().parents[1] / 'ros2_ws' / 'src' / 'ibvs_bringup' / 'config'
SHIPPED = sorted(CONFIG.glob('*.yaml'))


def _values(path):
    return yaml.safe_load(path.read_text())['/**']['ros__parameters']


def _config(cls, values):
    """Return ``cls`` built from the file's values of its own parameters (defaults elsewhere)."""
    names = {spec.name for spec in cls.params()}
    return cls.make(**{k: v for k, v in values.items() if k in names})


class _Logger:
    """Collect what a node would log as warnings."""

    def __init__(self):
        self.warnings = []

    def warn(self, text):
        self.warnings.append(text)

    warning = warn

    def get_logger(self):
        return self


def test_every_shipped_file_is_checked():
    assert {p.name for p in SHIPPED} >= {'scenario1.yaml', 'scenario2.yaml', 'scenario3.yaml',
                                         'real_cell.yaml', 'cell.yaml'}


@pytest.mark.parametrize('path', SHIPPED, ids=lambda p: p.name)
def test_no_shipped_file_sets_a_retired_parameter(path):
    assert not set(RETIRED) & set(_values(path)), path.name


@pytest.mark.parametrize('path', SHIPPED, ids=lambda p: p.name)
def test_the_joint_controller_warns_of_nothing_a_shipped_file_sets(path):
    config = _config(JointControllerConfig, _values(path))
    if config.interface.command_interface != 'position':
        return  # the effort interface reads every one of its parameters
    assert config.off_default(EFFORT_ONLY) == []
    logger = _Logger()
    PositionController._warn_ignored(logger, config)  # the start-up check itself
    assert logger.warnings == []


@pytest.mark.parametrize('path', SHIPPED, ids=lambda p: p.name)
def test_the_simulator_warns_of_nothing_a_shipped_file_sets(path):
    values = _values(path)
    if 'scenario' not in values:
        return  # cell.yaml: no simulator reads it (a real cell's controller side)
    config = _config(SimNodeConfig, values)
    if config.interface.lockstep:
        assert config.off_default(FREE_RUNNING_ONLY) == []
    else:
        assert config.min_frame_joint_state_subscribers == 0
