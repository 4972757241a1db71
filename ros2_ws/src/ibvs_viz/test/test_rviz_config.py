"""The shipped RViz config shows the graph's viewer topics with their publishers' QoS."""

from pathlib import Path
import re

from ibvs_common import contract
from ibvs_model import abb_urdf
import pytest
import yaml

PACKAGE = Path(__file__).resolve().parents[1]
CONFIG = PACKAGE / 'config' / 'ibvs.rviz'


def displays():
    """Return the config's displays as {class: [display, ...]}."""
    found = {}
    for display in yaml.safe_load(CONFIG.read_text())['Visualization Manager']['Displays']:
        found.setdefault(display['Class'], []).append(display)
    return found


def topic(display):
    """Return the topic setting of a display (RobotModel: its description topic)."""
    return display.get('Topic') or display['Description Topic']


def test_each_display_reads_a_topic_the_graph_publishes_with_its_qos():
    shown = displays()
    assert set(shown) == {f'rviz_default_plugins/{name}' for name in
                          ('Grid', 'RobotModel', 'TF', 'MarkerArray', 'Image')}
    (robot,) = shown['rviz_default_plugins/RobotModel']
    assert robot['Description Source'] == 'Topic'
    assert topic(robot)['Value'] == contract.ROBOT_DESCRIPTION
    # robot_state_node publishes it once, latched: only a transient local reader gets it.
    assert contract.LATCHED.durability.name == 'TRANSIENT_LOCAL'
    assert topic(robot)['Durability Policy'] == 'Transient Local'
    (markers,) = shown['rviz_default_plugins/MarkerArray']
    assert topic(markers)['Value'] == contract.MARKERS
    assert sorted(topic(d)['Value'] for d in shown['rviz_default_plugins/Image']) == \
        sorted((contract.DEBUG_LEFT_IMAGE, contract.DEBUG_RIGHT_IMAGE))
    for display in shown['rviz_default_plugins/Image'] + [markers]:
        assert topic(display)['Durability Policy'] == 'Volatile'
    for display in [robot, markers, *shown['rviz_default_plugins/Image']]:
        # Every publisher of these is reliable (contract.IMAGES, LATCHED, viz_node's depth 10).
        assert topic(display)['Reliability Policy'] == 'Reliable'


def test_the_view_is_fixed_on_abbs_base_link():
    config = yaml.safe_load(CONFIG.read_text())['Visualization Manager']
    assert config['Global Options']['Fixed Frame'] == abb_urdf.BASE_FRAME


@pytest.mark.parametrize('name', ['ibvs.rviz', 'foxglove_layout.json'])
def test_setup_py_installs_the_viewer_configs(name):
    setup = (PACKAGE / 'setup.py').read_text()
    patterns = re.findall(r"glob\('config/([^']+)'\)", setup)
    assert any(Path(name).match(pattern) for pattern in patterns), patterns
