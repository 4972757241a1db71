"""
docs/design.md §2's new node, taken from the page as written and run beside another node.

So the example a newcomer copies cannot rot: it must import, build on the kit (typed
configuration, publisher, subscription, wait reporter: no QoS, parameter declaration or
wait logger by hand), answer joint states and honour its parameter.
"""

from pathlib import Path
import re
import time
import types

from ibvs_common import contract, kit
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

DESIGN = Path(__file__).resolve().parents[1] / 'docs' / 'design.md'


def _example():
    section = DESIGN.read_text().split('\n### A new node on the kit\n', 1)[1]
    return re.search(r'```python\n(.*?)```', section, re.DOTALL).group(1)


def _load():
    module = types.ModuleType('design_example')
    exec(compile(_example(), str(DESIGN), 'exec'), module.__dict__)  # noqa: S102 (our page)
    return module


def test_the_example_is_short_and_writes_no_plumbing():
    code = _example()
    body = [line for line in code.splitlines()
            if line.strip() and not line.startswith(('from ', 'import '))]
    assert len(body) <= 20, len(body)
    for plumbing in ('QoSProfile', 'declare_parameter', 'create_publisher',
                     'create_subscription', 'create_timer', 'get_logger'):
        assert plumbing not in code, plumbing


@pytest.mark.parametrize('scale', [1.0, 2.5])
def test_the_example_runs_beside_another_node(context, scale):
    example = _load()
    node = example.SpeedNode(context=context,
                             parameter_overrides=[Parameter('scale', value=scale)])
    other = rclpy.create_node('joint_source', context=context)
    executor = SingleThreadedExecutor(context=context)
    got = []
    try:
        assert node.config == example.SpeedConfig(scale=scale)
        assert 'factor on the speed' in node.describe_parameter('scale').description
        assert {(e.topic, e.direction) for e in kit.opened(node)} == {
            ('/fastest_joint', kit.PUBLISHES), (contract.JOINT_STATES, kit.SUBSCRIBES)}
        pub = other.create_publisher(JointState, contract.JOINT_STATES, contract.RELIABLE)
        other.create_subscription(Float64, '/fastest_joint', lambda m: got.append(m.data),
                                  contract.RELIABLE)
        executor.add_node(node)
        executor.add_node(other)
        msg = JointState(name=list(contract.JOINT_NAMES), position=[0.0] * 6,
                         velocity=[0.5, -3.0, 1.0, 0.0, 0.0, 2.0])
        deadline = time.monotonic() + 10.0
        while not got and time.monotonic() < deadline:
            pub.publish(msg)
            executor.spin_once(timeout_sec=0.05)
        assert got and got[0] == pytest.approx(3.0 * scale)
    finally:
        executor.shutdown()
        other.destroy_node()
        node.destroy_node()


def test_the_example_refuses_a_bad_parameter(context):
    from ibvs_common.params import ParameterError
    example = _load()
    with pytest.raises(ParameterError, match="'scale'"):
        example.SpeedNode(context=context, parameter_overrides=[Parameter('scale', value=-1.0)])
