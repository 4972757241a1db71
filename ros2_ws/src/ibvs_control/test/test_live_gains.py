"""The feedback node's gains set at run time (``ros2 param set``), checked as at start."""

from ibvs_control.adaptive_feedback_node import AdaptiveFeedbackNode
from ibvs_control.servo_laws import AdaptiveGain
import pytest
from rclpy.parameter import Parameter


@pytest.fixture
def node(context):
    node = AdaptiveFeedbackNode(context=context, parameter_overrides=[
        Parameter('servo_law', value='ibvs'), Parameter('feedforward_method', value='hold')])
    yield node
    node.destroy_node()


def test_a_live_gain_is_taken_and_reaches_the_law(node):
    result = node.set_parameters([Parameter('lambda_0', value=6.0)])[0]
    assert result.successful, result.reason
    assert node.gain == AdaptiveGain(6.0, node.gain.lambda_inf, node.gain.lambda_slope)
    assert node.get_parameter('lambda_0').value == 6.0


def test_a_live_gain_out_of_range_or_against_the_others_is_refused_naming_why(node):
    # beyond the descriptor's range: rclpy's own refusal, with the range
    result = node.set_parameters([Parameter('lambda_0', value=-1.0)])[0]
    assert not result.successful and 'Max: 1000.0' in result.reason
    # within it but not allowed (the range is open at 0): the node's, as at start
    result = node.set_parameters([Parameter('lambda_0', value=0.0)])[0]
    assert not result.successful
    assert "'lambda_0'" in result.reason and '(0, 1000]' in result.reason
    result = node.set_parameters([Parameter('lambda_0', value=1.0)])[0]  # below lambda_inf 3
    assert not result.successful and 'lambda_inf <= lambda_0' in result.reason
    assert node.get_parameter('lambda_0').value == 12.0


def test_a_structural_parameter_stays_read_only(node):
    result = node.set_parameters([Parameter('omega_n', value=5.0)])[0]
    assert not result.successful and 'read-only' in result.reason
    assert node.describe_parameter('omega_n').read_only
    assert not node.describe_parameter('lambda_0').read_only
