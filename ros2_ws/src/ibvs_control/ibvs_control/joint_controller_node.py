"""
joint_controller_node: the inner joint loop of section 4.1, q_ref = q_feedforward + q_feedback.

One class per command interface, picked at start by ``command_interface``:

- 'effort' (:class:`.effort_controller.EffortController`, lockstep): on each /joint_states
  one computed-torque command stamped like it on /joint_effort_commands; reads
  /ibvs/feedforward_trajectory, /ibvs/q_feedback and /stereo/frame_lost.
- 'position' (:class:`.position_controller.PositionController`, free-running): position
  references at ``command_rate_hz`` on /forward_position_controller/commands or
  /joint_trajectory_controller/joint_trajectory, /ibvs/frame_latency and
  /ibvs/servo_status; reads /joint_states, /stereo/left/camera_info, the feedforward and
  the q_feedback.

Parameters: :class:`.node_params.JointControllerConfig` (docs/parameters.md).
Bad input is rejected, logged and counted on /diagnostics, never raised. The rules of each
interface (stamps, buffering, lost frames, stopping safely): docs/nodes.md.
"""

from typing import Any

from ibvs_common.diagnostics import Diagnostics
from ibvs_common.kit import config
from ibvs_common.node_main import run
from rclpy.node import Node

from .effort_controller import EffortController
from .node_params import JointControllerConfig
from .position_controller import PositionController

#: The node's typed configuration, built by ``ibvs run`` before any node starts.
CONFIG = JointControllerConfig
PARAMS = CONFIG.params()
#: command_interface -> the class that runs it.
MODES = {'effort': EffortController, 'position': PositionController}
#: Rules between parameters, run at start and by ``ibvs run`` before any node starts.
RULES = CONFIG.RULES


class JointControllerNode(Node):
    """The node adapter: the config, the diagnostics and the mode (module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        """Declare and check the parameters, then start the command interface's class."""
        super().__init__('joint_controller_node', **kwargs)
        self.config = config(self, JointControllerConfig)
        self.mode = None
        self.diagnostics = Diagnostics(self, 'joint controller')
        self.mode = MODES[self.config.interface.command_interface](self, self.config)

    def destroy_node(self) -> None:
        """Release what the mode holds with the node."""
        if self.mode is not None:
            self.mode.close()
        return super().destroy_node()


def main(args: list[str] | None = None) -> None:
    """Run the joint controller node (``ros2 run ibvs_control joint_controller_node``)."""
    run(JointControllerNode, args=args, name='joint_controller_node')


if __name__ == '__main__':
    main()
