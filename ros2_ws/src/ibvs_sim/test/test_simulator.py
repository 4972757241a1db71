"""The ROS-free simulator: configuration checks, start pose, encoders, frame schedule."""

from pathlib import Path
import re

from ibvs_common import shared_params
from ibvs_common.params import ParameterError
from ibvs_common.timing import frame_stamp_ns
from ibvs_model import forward_kinematics, paper, pose_error
from ibvs_sim.node_params import SimConfig
from ibvs_sim.simulator import Simulator
import numpy as np
import pytest
import yaml


def config(**values):
    """Return the SimConfig of ``values``."""
    return SimConfig.make(**values)


@pytest.fixture(scope='module')
def sim():
    s = Simulator(config(scenario=1, disturbance_deg=paper.DISTURBANCE_DEG))
    try:
        yield s
    finally:
        s.close()


def test_true_start_pose_is_the_scenario_pose(sim):
    """The TRUE angles reach the start pose; the encoders read them minus d_q."""
    q, qd = sim.true_state()
    pos_err, rot_err = pose_error(forward_kinematics(q, sim.params),
                                  paper.scenario_start_pose(1))
    assert pos_err < 1e-9 and rot_err < 1e-9
    assert sim.start_residual[0] < 1e-9
    q_enc, qd_enc = sim.encoders()
    assert np.allclose(q_enc, q - np.radians(paper.DISTURBANCE_DEG), atol=1e-15)
    assert np.all(qd_enc == qd)
    assert np.allclose(sim.tool_pose(), forward_kinematics(q, sim.params))


def test_scaled_robot_reaches_the_start_with_other_angles():
    """Figure 13: the simulated robot's L2, L4 differ; its true angles still reach the pose."""
    scaled = Simulator(config(scenario=2, l2_scale=1.05, l4_scale=0.95))
    plain = Simulator(config(scenario=2))
    try:
        assert scaled.params.L2 == pytest.approx(0.9 * 1.05)
        assert scaled.params.L4 == pytest.approx(0.96 * 0.95)
        pose = forward_kinematics(scaled.true_state()[0], scaled.params)
        assert pose_error(pose, paper.scenario_start_pose(2))[0] < 1e-9
        assert np.abs(scaled.q_start - plain.q_start).max() > 1e-3
    finally:
        scaled.close()
        plain.close()


def test_frame_schedule_30_hz_on_1_khz(sim):
    """Frame n is due at n * T_cam, taken at the first step at or after it, stamped then."""
    assert sim.dt_ns == 1_000_000 and sim.camera_period_ns == 33_333_333
    assert not sim.frames_exact
    k0 = sim.k
    taken = []
    for _ in range(201):
        if sim.frame_due() is not None:
            stamp, images, lost = sim.take_frame(render=False)
            assert not lost
            assert images is None
            taken.append((stamp, sim.t_ns))
        sim.step(sim.hold_torque())
    assert [t for _, t in taken] == [0, 34_000_000, 67_000_000, 100_000_000, 134_000_000,
                                     167_000_000, 200_000_000]
    assert [s for s, _ in taken] == [t for _, t in taken]
    assert [s for s, _ in taken] == [frame_stamp_ns(n, 33_333_333, 1_000_000)
                                     for n in range(len(taken))]
    assert sim.k == k0 + 201
    with pytest.raises(RuntimeError):
        sim.take_frame()  # none due right after a frame


def test_frames_on_steps_when_the_camera_period_is_whole_steps():
    s = Simulator(config(physics_rate_hz=1000.0, camera_rate_hz=50.0))
    try:
        assert s.frames_exact
        stamps = []
        for _ in range(100):
            if s.frame_due() is not None:
                stamps.append(s.take_frame(render=False)[0])
                assert stamps[-1] == s.t_ns
            s.step()
        assert stamps == [n * 20_000_000 for n in range(5)]
    finally:
        s.close()


def test_step_checks_the_torque(sim):
    with pytest.raises(ValueError):
        sim.step([0.0] * 5)
    with pytest.raises(ValueError):
        sim.step([0.0, 0.0, np.nan, 0.0, 0.0, 0.0])


@pytest.mark.parametrize('kwargs, param', [
    ({'physics_rate_hz': -1000.0}, 'physics_rate_hz'),
    ({'camera_rate_hz': 0.0}, 'camera_rate_hz'),
    ({'camera_rate_hz': 2000.0}, 'camera_rate_hz'),
    ({'scenario': 4}, 'scenario'),
    ({'l2_scale': 0.3, 'l4_scale': 0.3}, 'scenario'),
    ({'camera_eye': (1.0, 1.0, 1.0), 'camera_look_at': (1.0, 1.0, 1.0)}, 'camera_look_at'),
    ({'camera_eye': (0.0, 0.0, 3.0), 'camera_look_at': (0.0, 0.0, 0.0)}, 'camera_look_at'),
    ({'resolution': 'QVGA'}, 'resolution'),
    ({'disturbance_deg': (0.0,) * 5}, 'disturbance_deg'),
    ({'mount_height_m': -0.5}, 'mount_height_m'),
    ({'render_marker_supersampling': 0}, 'render_marker_supersampling'),
])
def test_bad_configuration_names_the_parameter(kwargs, param):
    with pytest.raises(ParameterError) as info:
        Simulator(config(**kwargs))
    assert info.value.param == param
    assert f"'{param}'" in str(info.value)


def test_scenario_files_hold_the_paper_values():
    """ibvs_bringup/config/scenario{1,2,3}.yaml: sim time, shared names only, values allowed."""
    config = Path(__file__).resolve().parents[2] / 'ibvs_bringup' / 'config'
    specs = {p.name: p for p in vars(shared_params).values()
             if isinstance(p, shared_params.Param)}
    for n in (1, 2, 3):
        data = yaml.safe_load((config / f'scenario{n}.yaml').read_text())
        params = dict(data['/**']['ros__parameters'])
        # rclpy's own parameter: every node follows /clock (docs/design.md §4).
        assert params.pop('use_sim_time') is True
        assert set(params) <= set(specs), set(params) - set(specs)
        for name, value in params.items():
            specs[name].check(value)
        assert params['scenario'] == n
        expected = paper.DISTURBANCE_DEG if n in (1, 3) else (0.0,) * 6
        assert params['disturbance_deg'] == list(expected)
        assert params['target_position'] == list(paper.TARGET_POSITION)
        assert np.reshape(params['target_rotation'], (3, 3)).tolist() == \
            [list(r) for r in paper.TARGET_ROTATION]
        assert (params['tau_in'], params['omega_n'], params['zeta']) == \
            (paper.TAU_IN, paper.OMEGA_N, paper.ZETA)
        assert (params['camera_rate_hz'], params['physics_rate_hz']) == (30.0, 1000.0)
        assert params['feedback_latency_s'] == 0.0 and params['actuators'] == 'ideal'
        assert (params['l2_scale'], params['l4_scale']) == (1.0, 1.0)


def test_installed_urdf_is_the_generated_one():
    """urdf/irb4600_screwdriver.urdf (installed to share/ibvs_sim/urdf) is up to date."""
    from ibvs_model.mesh import icosphere_obj, MARKER_MESH
    from ibvs_model.urdf import robot_urdf
    path = Path(__file__).resolve().parents[1] / 'urdf' / 'irb4600_screwdriver.urdf'
    assert (path.parent / MARKER_MESH).read_text() == icosphere_obj()
    # The same text but for the numbers' last bits, which differ between CPU kernels (BLAS):
    # each number within 1e-12 relative (1e-15 absolute near 0).
    installed, generated = path.read_text(), robot_urdf()
    number = re.compile(r'-?\d+\.?\d*(?:[eE][-+]?\d+)?')
    regenerate = ('regenerate: python -c "from ibvs_model.urdf import write_urdf; '
                  f"write_urdf('{path}')\"")
    assert number.sub('#', installed) == number.sub('#', generated), regenerate
    np.testing.assert_allclose([float(x) for x in number.findall(installed)],
                               [float(x) for x in number.findall(generated)],
                               rtol=1e-12, atol=1e-15, err_msg=regenerate)
