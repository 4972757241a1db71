"""
The joint controller's ear on /ibvs/feedback_status: what the feedback node reports.

The joint controller is the one publisher of /ibvs/servo_status; what only the feedback
node can tell (a local minimum of the image error, :mod:`.minimum_watch`) it reports on
/ibvs/feedback_status, and :func:`relay` hands each change to the controller, which lays
it over its own verdict (:meth:`.servo_status.FeedbackStatus.over`) and says it beside its
own status on /diagnostics (an alert: WARN).
"""

from collections.abc import Callable
from typing import TYPE_CHECKING

from ibvs_common import contract
from ibvs_common.kit import subscription
from std_msgs.msg import Int8

from .servo_status import FeedbackStatus, ServoStatus

if TYPE_CHECKING:
    from ibvs_common.diagnostics import Diagnostics
    from rclpy.node import Node

#: The /diagnostics alert key of a relayed warning.
ALERT_KEY = 'feedback_status'


def relay(node: 'Node', diagnostics: 'Diagnostics',
          on_change: Callable[[], None] = lambda: None) -> FeedbackStatus:
    """
    Subscribe to /ibvs/feedback_status; return the status it keeps up to date.

    A code the feedback node does not report is rejected (counted on /diagnostics, the
    status unchanged); on each change ``on_change()`` is called, and the alert set (a
    warning) or cleared (NO_WARNING).
    """
    status = FeedbackStatus()

    def take(msg):
        try:
            changed = status.take(int(msg.data))
        except ValueError as exc:
            diagnostics.reject(contract.FEEDBACK_STATUS, 'unknown code', str(exc))
            return
        if not changed:
            return
        warning = status.status != ServoStatus.NO_WARNING
        diagnostics.alert(ALERT_KEY, f'the feedback node reports {status.status.name}'
                          if warning else None)
        diagnostics.update(feedback_status=status.status.name)
        on_change()

    subscription(node, Int8, contract.FEEDBACK_STATUS, take, contract.LATCHED)
    return status
