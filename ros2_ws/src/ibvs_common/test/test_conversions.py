"""ibvs_common.conversions: every name it has held, re-exported from its message module."""

import importlib

from ibvs_common import conversions
import pytest

#: Each name importable from ibvs_common.conversions, by the module that holds it: those
#: the nodes and tests import, and the private ones they reach through it.
NAMES = {
    'input_error': ['InputError'],
    'msg_time': ['stamp_ns', 'read_stamp', 'StampOrder', 'ns_stamp', 'duration_ns'],
    'timing': ['STAMP_LEAD_MARGIN_NS', 'stamp_lead_ns'],
    'msg_joints': ['POSITION_MARGIN_RAD', 'POSITION_BOUND_RAD', 'SPEED_BOUND_RAD_S',
                   'joint_state', 'JOINT_ORDER_CACHE', '_JOINT_ORDERS', 'joint_order',
                   'ignored_joints', 'JOINT_FIELDS', 'read_joints', 'travel_bounds',
                   '_symmetric_bounds', '_POSITION_BOUNDS', '_VELOCITY_BOUNDS',
                   'position_bounds', 'velocity_bounds', 'check_finite'],
    'msg_trajectory': ['joint_trajectory', 'trajectory_arrays', 'read_trajectory',
                       'read_command_trajectory', 'joint_path', 'read_joint_path'],
    'msg_pose': ['pose_matrix', 'matrix_poses', 'transforms_msg', 'matrix_pose',
                 'pose_stamped', 'path_msg', 'MAX_CAMERA_DISTANCE_M', 'read_camera_pose'],
    'msg_camera': ['image_msg', 'camera_infos', 'MAX_IMAGE_SIDE_PX', 'FOV_RANGE_DEG',
                   'BASELINE_RANGE_M', 'ROW_TOLERANCE_PX', 'PINHOLE_TOLERANCE', 'CU_TOLERANCE',
                   'focal_range_px', 'check_camera_info', 'intrinsics_from_infos',
                   'camera_from_msgs'],
    'msg_features': ['features_msg', 'read_features', 'IMAGE_MARGIN_PX',
                     'check_features_in_image', 'FeatureStatus', 'feature_status_msg',
                     'read_feature_status'],
}


@pytest.mark.parametrize('module, name', [(m, n) for m, names in NAMES.items() for n in names])
def test_every_name_of_conversions_is_the_object_of_its_message_module(module, name):
    held = importlib.import_module(f'ibvs_common.{module}')
    assert getattr(conversions, name) is getattr(held, name)


def test_the_public_names_of_conversions_are_the_ones_it_exports_and_no_other():
    listed = {n for names in NAMES.values() for n in names}
    public = {n for n in listed if not n.startswith('_')}
    assert sorted(conversions.__all__) == sorted(public)
    assert len(conversions.__all__) == len(set(conversions.__all__))


def test_a_name_is_defined_in_one_message_module_only():
    """A name of one module is not redefined in another: each module owns what it holds."""
    for module, names in NAMES.items():
        held = importlib.import_module(f'ibvs_common.{module}')
        for name in names:
            value = getattr(held, name)
            if callable(value) and hasattr(value, '__module__'):
                assert value.__module__ == held.__name__, name


def test_the_joint_order_cache_read_through_conversions_is_the_one_joint_order_keeps():
    from ibvs_common import contract, msg_joints
    names = list(contract.JOINT_NAMES) + ['track_of_the_cache_test']
    conversions.joint_order(names)
    assert (tuple(names), tuple(contract.JOINT_NAMES)) in conversions._JOINT_ORDERS
    assert conversions._JOINT_ORDERS is msg_joints._JOINT_ORDERS
