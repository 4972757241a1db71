"""The workspace's tf2_msgs is Jazzy's: the same TFMessage type hash on the wire and in bags."""

from ibvs_testing.fixtures import context  # noqa: F401
import rclpy
from rosbags.typesys import get_typestore, Stores
from tf2_msgs.msg import TFMessage

#: The RIHS01 hash of tf2_msgs/msg/TFMessage in ROS 2 Jazzy (geometry2): RViz, tf2_ros and
#: Foxglove on a full install match publishers by it.
JAZZY_TF_MESSAGE_HASH = \
    'RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087'


def test_tf_message_type_hash_on_the_wire(context):  # noqa: F811
    node = rclpy.create_node('tf_hash_probe', context=context)
    try:
        node.create_publisher(TFMessage, '/tf', 10)
        infos = node.get_publishers_info_by_topic('/tf')
        assert [str(i.topic_type_hash) for i in infos] == [JAZZY_TF_MESSAGE_HASH]
        assert infos[0].topic_type == 'tf2_msgs/msg/TFMessage'
    finally:
        node.destroy_node()


def test_bag_type_store_agrees():
    """The recorder writes bags with rosbags' Jazzy type store: the same definition."""
    store = get_typestore(Stores.ROS2_JAZZY)
    assert store.hash_rihs01('tf2_msgs/msg/TFMessage') == JAZZY_TF_MESSAGE_HASH
    fields = TFMessage.get_fields_and_field_types()
    assert fields == {'transforms': 'sequence<geometry_msgs/TransformStamped>'}
