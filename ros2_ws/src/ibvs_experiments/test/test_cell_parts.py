"""``ibvs cell``'s parts without a graph: its parameters, remaps, topic check and status line."""

from pathlib import Path

from ibvs_bringup import scenario
from ibvs_common import contract
from ibvs_experiments import cell, cli
import numpy as np
import pytest
import yaml

CONFIG = Path(__file__).resolve().parents[2] / 'ibvs_bringup' / 'config'
LEFT = '/zed/zed_node/left/color/rect/image'


def load(name):
    return yaml.safe_load((CONFIG / name).read_text())['/**']['ros__parameters']


def test_cell_yaml_is_real_cell_less_the_simulators_keys_on_the_wall_clock():
    params, real = load('cell.yaml'), load('real_cell.yaml')
    declared = cell.declared_by(cell.CELL_NODES)
    # Every key is read by one of the four nodes (use_sim_time: by every ROS node).
    assert [k for k in params if k not in declared] == ['use_sim_time']
    assert cell.simulator_only(params) == []
    assert params['use_sim_time'] is False
    # Nothing of real_cell.yaml that a cell's node reads is left out, and no value differs
    # but the speed cap: a first run on abb_ros2's example RAPID (20 deg/s) against the
    # rehearsal's 60 deg/s (docs/real_cell.md, a first run's speed); and a first run knows
    # no stamp offset, where the rehearsal starts from an earlier run's estimate.
    kept = {k: v for k, v in real.items() if k in declared}
    assert params['max_joint_speed_deg_s'] == 20.0 < kept['max_joint_speed_deg_s']
    assert 'stamp_offset_initial_s' not in params and kept['stamp_offset_initial_s'] != 0.0
    first_run = ('use_sim_time', 'max_joint_speed_deg_s', 'stamp_offset_initial_s')
    assert {k: v for k, v in params.items() if k not in first_run} == \
        {k: v for k, v in kept.items() if k not in first_run}
    # What was left out is the simulator's or the runner's (real_cell.yaml has several).
    dropped = set(real) - set(params)
    assert dropped == set(cell.simulator_only(real)) | {'run_duration_s',
                                                        'stamp_offset_initial_s'}
    assert {'real_time_factor', 'camera_topics', 'command_timeout_s',
            'image_noise_stddev'} <= dropped


def test_cell_yaml_is_installed_with_the_scenarios():
    setup = (CONFIG.parent / 'setup.py').read_text()
    assert "glob('config/*.yaml')" in setup
    assert cell.config_path().name == 'cell.yaml'
    assert cell.config_path().is_file()


def test_default_remaps_take_abb_ros2s_controller_and_the_wrappers_topics():
    remaps = cell.remaps()
    assert remaps['feature_node'] == {
        contract.LEFT_IMAGE: LEFT,
        contract.RIGHT_IMAGE: '/zed/zed_node/right/color/rect/image',
        contract.LEFT_INFO: '/zed/zed_node/left/color/rect/camera_info',
        contract.RIGHT_INFO: '/zed/zed_node/right/color/rect/camera_info'}
    assert remaps['adaptive_feedback_node'] == {
        contract.LEFT_INFO: '/zed/zed_node/left/color/rect/camera_info',
        contract.RIGHT_INFO: '/zed/zed_node/right/color/rect/camera_info'}
    assert remaps['joint_controller_node'] == {
        contract.LEFT_INFO: '/zed/zed_node/left/color/rect/camera_info',
        contract.RIGHT_INFO: '/zed/zed_node/right/color/rect/camera_info',
        contract.POSITION_COMMANDS: '/forward_command_controller_position/commands'}
    assert 'feedforward_node' not in remaps  # it reads /joint_states only
    # /joint_states is the driver's: nobody's is remapped (no simulator's /stereo/...).
    assert all(contract.JOINT_STATES not in m for m in remaps.values())
    assert cell.remap_args(remaps['joint_controller_node'])[-2:] == (
        '-r', f'{contract.POSITION_COMMANDS}:=/forward_command_controller_position/commands')


def test_options_map_to_remaps():
    remaps = cell.remaps('joint_trajectory', camera_name='cam_a')
    assert remaps['feature_node'][contract.LEFT_IMAGE] == '/cam_a/zed_node/left/color/rect/image'
    # abb_ros2's joint_trajectory_controller has the contract's name: no remap of it.
    assert contract.TRAJECTORY_COMMANDS not in remaps['joint_controller_node']
    assert cell.command_topic('joint_trajectory') == contract.TRAJECTORY_COMMANDS
    renamed = cell.remaps('forward_command', controller_name='my_position')
    assert renamed['joint_controller_node'][contract.POSITION_COMMANDS] == \
        '/my_position/commands'
    for bad in ({'camera_name': 'zed/x'}, {'controller_name': '1x'}):
        with pytest.raises(cell.CellError):
            cell.remaps(**bad)
    with pytest.raises(cell.CellError, match='forward_command, joint_trajectory'):
        cell.remaps('velocity')


def test_parameters_refuse_the_simulators_keys_and_a_conflicting_command_type():
    params = cell.cell_parameters()
    assert params['position_command_type'] == 'forward_command'
    assert params['use_sim_time'] is False
    assert cell.cell_parameters(controller='joint_trajectory')['position_command_type'] == \
        'joint_trajectory'
    with pytest.raises(cell.CellError, match='real_time_factor'):
        cell.cell_parameters(overrides={'real_time_factor': 0.1})
    with pytest.raises(cell.CellError, match="'joint_trajectory' with --controller"):
        cell.cell_parameters(overrides={'position_command_type': 'joint_trajectory'})
    with pytest.raises(cell.CellError, match="parameter 'lockstep' is retired: the time mode "
                       'follows from command_interface'):
        cell.cell_parameters(overrides={'lockstep': False})
    with pytest.raises(cell.CellError, match='command_rate_hz'):
        cell.cell_parameters(overrides={'command_rate_hz': -1.0})
    with pytest.raises(cell.CellError, match='does not exist'):
        cell.cell_parameters('/nonexistent/cell.yaml')


def endpoint(msg_type, reliability='reliable', durability='volatile'):
    return cell.Endpoint('/zed/zed_node', msg_type, reliability, durability)


def everything(expected):
    """Return the endpoints of a cell where everything is there, as our side asks."""
    return {e.topic: [endpoint(e.msg_type, e.reliability, e.durability)] for e in expected}


def test_nothing_there_names_each_topic_and_what_to_look_at():
    expected = cell.expectations(cell.cell_parameters())
    found = cell.problems(expected, {})
    assert found[0].startswith(f'no {LEFT}: is video.publish_left_right true? '
                               '(zed-ros2-wrapper common_stereo.yaml L54 defaults it to false')
    assert any(p.startswith('no /joint_states: ') for p in found)
    assert ('no subscriber on /forward_command_controller_position/commands: is the '
            'controller spawned?') in '\n'.join(found)
    # cell.yaml: camera_pose zeros and a taught target, so those must be there too.
    assert any(p.startswith(f'no {contract.STEREO_POSE}: ') for p in found)
    assert any(p.startswith(f'no {contract.TEACH_LEFT_IMAGE}: ') for p in found)
    assert len(found) == len(expected) == 9
    assert cell.problems(expected, everything(expected)) == []


def test_a_calibrated_camera_and_a_model_target_need_neither_pose_nor_teach_pair():
    params = cell.cell_parameters(overrides={
        'camera_pose': [1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0], 'target_features_source': 'model'})
    topics = [e.topic for e in cell.expectations(params, camera_name='cam')]
    assert contract.STEREO_POSE not in topics
    assert contract.TEACH_LEFT_IMAGE not in topics
    assert '/cam/zed_node/left/color/rect/image' in topics


def test_type_and_qos_mismatches_are_named():
    expected = cell.expectations(cell.cell_parameters())
    found = everything(expected)
    found[LEFT] = [endpoint('sensor_msgs/msg/Image', reliability='best_effort')]
    found[contract.JOINT_STATES] = [endpoint('sensor_msgs/msg/Imu')]
    found[contract.STEREO_POSE] = [endpoint('geometry_msgs/msg/PoseStamped')]  # volatile
    command = '/forward_command_controller_position/commands'
    # A subscription that asks for transient local gets nothing from our volatile publisher.
    found[command] = [endpoint('std_msgs/msg/Float64MultiArray', durability='transient_local')]
    result = cell.problems(expected, found)
    assert len(result) == 4
    assert f'{LEFT}: publisher /zed/zed_node: QoS reliability: the publisher is best_effort' \
        in result[0]
    assert 'type sensor_msgs/msg/Imu, expected sensor_msgs/msg/JointState' in result[1]
    assert 'QoS durability' in result[2] and command in result[2]
    assert contract.STEREO_POSE in result[3] and 'QoS durability' in result[3]
    # One matching endpoint among others is enough.
    found[LEFT].append(endpoint('sensor_msgs/msg/Image'))
    assert len(cell.problems(expected, found)) == 3


def test_status_board_says_the_servo_status_frames_and_last_error():
    now = [100.0]
    board = cell.StatusBoard(clock=lambda: now[0])
    assert board.line() == ('[     0 s] servo: no status yet | frames used 0 | '
                            'last error: none')
    board.servo(10)
    board.diagnostics('joint_controller_node: joint loop', 0, 'waiting for feedback',
                      {'servo_status': 'WAITING', 'rejected_total': '0'})
    assert 'servo 10 WAITING (waiting for feedback)' in board.line()
    board.servo(0)
    board.diagnostics('joint_controller_node: joint loop', 0, 'ok',
                      {'servo_status': 'NO_WARNING'})
    for stamp in (1, 2, 2, 3):  # a frame counts once, whatever its commands
        board.frame_used(stamp)
    now[0] = 105.0
    board.diagnostics('feature_node: features', 0, 'ok',
                      {'rejected[/stereo/left/image_raw: encoding]': '2'})
    now[0] = 107.0
    assert board.line() == ('[     7 s] servo 0 NO_WARNING | frames used 3 | last error: '
                            'feature_node /stereo/left/image_raw: encoding (2 so far) (2 s ago)')
    # The same count again is no new error; a WARN status is.
    board.diagnostics('feature_node: features', 0, 'ok',
                      {'rejected[/stereo/left/image_raw: encoding]': '2'})
    assert board.last_error_at == 105.0
    board.diagnostics('joint_controller_node: joint loop', 1, 'camera stale: holding',
                      {'servo_status': 'HOLD_STALE_CAMERA'})
    board.servo(12)
    assert 'servo 12 HOLD_STALE_CAMERA (camera stale: holding)' in board.line()
    assert 'last error: joint_controller_node: camera stale: holding (0 s ago)' in board.line()
    board.servo(99)
    assert 'servo 99 (unknown code)' in board.line()


def test_status_board_says_clock_stopped_from_the_code_alone():
    """A dead simulator in the sim-time rehearsal: /clock stops, the code says so at once."""
    board = cell.StatusBoard(clock=lambda: 0.0)
    board.servo(0)
    board.diagnostics('joint_controller_node: joint loop', 0, 'ok',
                      {'servo_status': 'NO_WARNING'})
    board.servo(15)  # HOLD_CLOCK_STOPPED, before the next /diagnostics
    assert 'servo 15 HOLD_CLOCK_STOPPED (clock stopped)' in board.line()
    detail = 'clock stopped: /clock has not moved for 5.2 s of wall time (bound 5.0 s)'
    board.diagnostics('joint_controller_node: joint loop', 1, detail,
                      {'servo_status': 'HOLD_CLOCK_STOPPED'})
    assert f'servo 15 HOLD_CLOCK_STOPPED ({detail})' in board.line()
    board.servo(14)
    assert 'servo 14 HOLD_CLOCK_JUMPED_BACK (clock jumped back)' in board.line()


def test_status_board_names_a_second_publisher_at_once_and_drops_it_when_gone():
    """A rogue commander: the code and the newcomer are news (a line at once), then gone."""
    board = cell.StatusBoard(clock=lambda: 0.0)
    board.servo(0)
    assert board.take_news() and not board.take_news()
    command = '/forward_command_controller_position/commands'
    words = f'second publisher on {command}: /rogue'
    board.servo(16)  # HOLD_SECOND_PUBLISHER, maybe before /diagnostics
    assert board.take_news()
    assert 'servo 16 HOLD_SECOND_PUBLISHER (second publisher)' in board.line()
    board.diagnostics('joint_controller_node: joint loop', 1,
                      f'{words}: holding the arm until it is gone',
                      {'servo_status': 'HOLD_SECOND_PUBLISHER', 'second_publishers': words})
    board.diagnostics('sim_node: simulator', 1, 'second publisher on /x: /rogue',
                      {'second_publishers': 'second publisher on /x: /rogue'})
    assert board.take_news()
    line = board.line()
    assert (f'servo 16 HOLD_SECOND_PUBLISHER (second publisher) | {words} (seen by '
            'joint_controller_node) | second publisher on /x: /rogue (seen by sim_node) | '
            'frames used 0') in line
    board.diagnostics('sim_node: simulator', 1, 'second publisher on /x: /rogue',
                      {'second_publishers': 'second publisher on /x: /rogue'})
    assert not board.take_news(), 'the same words again are no news'
    board.diagnostics('joint_controller_node: joint loop', 0, 'ok',
                      {'servo_status': 'NO_WARNING', 'second_publishers': 'none'})
    board.servo(0)
    assert board.take_news() and command not in board.line().partition(' | frames')[0]


def test_ibvs_run_refuses_the_cells_file(capsys):
    assert cli.main(['run', 'cell']) == 2
    assert 'ibvs cell' in capsys.readouterr().err


def test_ibvs_cell_refuses_before_anything_starts(capsys, tmp_path):
    assert cli.main(['cell', '-o', str(tmp_path / 'x'), '-p', 'image_noise_stddev:=0.1']) == 2
    assert 'image_noise_stddev' in capsys.readouterr().err
    assert cli.main(['cell', '-o', str(tmp_path / 'x'), '--camera-name', 'a/b']) == 2
    assert 'camera name' in capsys.readouterr().err
    assert not (tmp_path / 'x').exists()
    with pytest.raises(SystemExit):
        cli.main(['cell', '--check-timeout', '-1'])


def test_scenario_listing_still_loads_cell_yaml():
    # cell.yaml is a valid parameters file (ibvs cell --params-file takes copies of it).
    assert scenario.load_parameters(cell.config_path())['command_interface'] == 'position'


def test_status_board_shows_the_image_and_pose_errors_and_a_dry_run():
    board = cell.StatusBoard(clock=lambda: 0.0, dry_run=True)
    board.servo(0)
    assert board.line().startswith('[     0 s] DRY RUN | servo 0 NO_WARNING | frames used')
    # Without a taught target: the feedback node's own error, said so.
    board.diagnostics('adaptive_feedback_node: feedback', 0, 'ok',
                      {'image_error_norm_px': '0.25'})
    assert " | image error 0.250 px (the feedback's) | " in board.line()
    # With one: |s - s*| of the features the loop used.
    board.target_px = np.array([640.0, 600.0, 360.0, 650.0, 610.0, 400.0])
    board.features_px = board.target_px + np.array([0.3, 0.0, 0.4, 0.0, 0.0, 0.0])
    board.pose_error(0.00042, 0.031)
    board.pose_error(None, None)  # no joint state readable: the last one stays
    assert (' | image error 0.500 px | pose error 0.420 mm, 0.031 deg | frames used 0'
            in board.line())


def test_the_pose_error_is_the_kinematics_of_the_newest_joint_state_against_the_target():
    from ibvs_common.conversions import joint_state
    from ibvs_model import forward_kinematics, inverse_kinematics, paper
    from rclpy.serialization import serialize_message
    target = paper.target_pose()
    q = inverse_kinematics(target)
    error = cell.PoseError(target)
    assert error(None) == (None, None)
    position, axis = error(serialize_message(joint_state(0, q)))
    assert position < 1e-9 and axis < 1e-6
    q[4] += np.radians(1.0)  # joint 5 tilts the tool axis by 1 deg
    moved = forward_kinematics(q)
    position, axis = error(serialize_message(joint_state(0, q)))
    assert position == pytest.approx(np.linalg.norm(moved[:3, 3] - target[:3, 3]))
    assert axis == pytest.approx(1.0, abs=1e-6)


def test_a_dry_run_wants_no_commanded_controller():
    params = cell.cell_parameters(overrides={'dry_run': True})
    topics = {e.topic for e in cell.expectations(params)}
    assert cell.command_topic('forward_command') not in topics
    assert cell.command_topic('forward_command') in {
        e.topic for e in cell.expectations(cell.cell_parameters())}
    assert cell.dry_run_topic('joint_trajectory') == contract.DRY_RUN_TRAJECTORY


def test_ibvs_cell_teach_refuses_a_target_of_its_own_and_a_folder_without_a_record(
        capsys, tmp_path):
    (tmp_path / 'none').mkdir()
    assert cli.main(['cell', '-o', str(tmp_path / 'x'), '--teach', str(tmp_path / 'none')]) == 2
    assert 'no teach folder' in capsys.readouterr().err
    assert not (tmp_path / 'x').exists()


def test_status_board_shows_the_cameras_stamp_offset_once_estimated():
    board = cell.StatusBoard(clock=lambda: 0.0)
    waiting = {'stamp_offset_ms': 'none', 'stamp_offset_sd_ms': 'none',
               'stamp_offset_state': 'waiting for the tool to move'}
    board.diagnostics('feature_node: stereo fiducial features', 0, 'measured', waiting)
    assert 'stamp offset' not in board.line()
    board.diagnostics('feature_node: stereo fiducial features', 0, 'measured',
                      {'stamp_offset_ms': '32.548', 'stamp_offset_sd_ms': '0.028',
                       'stamp_offset_state': 'estimating'})
    assert ' | stamp offset 32.5 +- 0.0 ms | ' in board.line()
    board.diagnostics('feature_node: stereo fiducial features', 0, 'measured',
                      {'stamp_offset_ms': '32.548', 'stamp_offset_sd_ms': '0.028',
                       'stamp_offset_state': 'holding: the tool is still'})
    assert 'stamp offset 32.5 +- 0.0 ms (holding: the tool is still)' in board.line()
