"""
``ibvs cell`` as a user starts it, on an empty domain and against the simulator.

On an empty domain it names what is missing; against the simulator standing in for the arm
and the ZED wrapper it starts, reports, and stops on one SIGINT leaving no process behind;
docs/real_cell.md's rehearsal (``ibvs teach``, then ``ibvs cell --teach``) converges and
leaves a bag ``ibvs analyse`` reads.

The simulator stands in as docs/real_cell.md "By hand" says: ``sim_node`` alone, free-running
with real_cell.yaml's keys (``camera_topics: zed_wrapper``: the wrapper's topic names), its
command topic remapped to abb_ros2's ``forward_command_controller_position``. The nodes run
on sim time here (``-p use_sim_time:=true``): the simulator's stamps are sim time.
"""

import json
import os
from pathlib import Path
import re
import signal
import subprocess
import sys
import time

from ibvs_common.process import supervised_child
from ibvs_testing.proc_tools import ProcTools
import pytest

ROOT = Path(__file__).resolve().parents[1]
REAL_CELL = ROOT / 'ros2_ws' / 'src' / 'ibvs_bringup' / 'config' / 'real_cell.yaml'
CELL_NODES = ('feature_node', 'adaptive_feedback_node', 'feedforward_node',
              'joint_controller_node')


def ibvs_cell(tmp_path, *args, stdout=subprocess.PIPE):
    return subprocess.Popen([sys.executable, '-m', 'ibvs_experiments.cli', 'cell', '-o',
                             str(tmp_path / 'cell'), *args], stdout=stdout,
                            stderr=subprocess.PIPE, text=True)


def test_nothing_on_the_domain_exits_naming_the_image_topic(installed_workspace, tmp_path):
    proc = ibvs_cell(tmp_path)
    try:
        out, err = proc.communicate(timeout=60.0)  # a hang guard: it waits 10 s (check-timeout)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 5, (out, err)
    assert 'no /zed/zed_node/left/color/rect/image: is video.publish_left_right true?' in err
    assert 'no subscriber on /forward_command_controller_position/commands' in err
    assert 'no node started' in err
    assert not list((tmp_path / 'cell' / 'logs').glob('*.log'))  # nothing was started


def test_a_downscaled_camera_is_refused_naming_pub_resolution(installed_workspace, tmp_path):
    """The wrapper's 'CUSTOM' resolution rehearsed: HD720 published at half its size."""
    with open(tmp_path / 'sim.log', 'w') as sim_log:
        sim = subprocess.Popen(
            [str(Path(installed_workspace) / 'lib' / 'ibvs_sim' / 'sim_node'), '--ros-args',
             '--params-file', str(REAL_CELL), '-p', 'pub_downscale_factor:=2.0',
             # as the ZED wrapper, it publishes to the first reader (the check's)
             '-p', 'min_command_publishers:=0', '-p', 'min_joint_state_subscribers:=0',
             '-r', '/forward_position_controller/commands:='
             '/forward_command_controller_position/commands'],
            stdout=sim_log, stderr=subprocess.STDOUT, preexec_fn=supervised_child)
        try:
            proc = ibvs_cell(tmp_path, '-p', 'use_sim_time:=true', '--check-timeout', '180')
            try:
                out, err = proc.communicate(timeout=300.0)
            finally:
                if proc.poll() is None:
                    proc.kill()
                    proc.communicate()
        finally:
            _stop(sim)
    assert proc.returncode == 5, (out, err)
    assert ("/zed/zed_node/left/color/rect/camera_info: 640 x 360 is none of the ZED 2's "
            'native sizes') in err
    assert 'general.pub_resolution:=NATIVE' in err and 'no node started' in err
    assert 'camera_info 640 x 360, f_x' in out
    assert not list((tmp_path / 'cell' / 'logs').glob('*.log'))  # nothing was started


@pytest.fixture
def cell_under_way(installed_workspace, tmp_path):
    """
    Start sim_node as the cell, then ``ibvs cell`` on it; yield once it reports.

    Yields ``(cell, out_path, seen)``: the ``ibvs cell`` process, its stdout's file (a status
    line already in it) and the pids seen below it. Teardown kills whatever is left.
    """
    sim_log = open(tmp_path / 'sim.log', 'w')
    sim = subprocess.Popen(
        [str(Path(installed_workspace) / 'lib' / 'ibvs_sim' / 'sim_node'), '--ros-args',
         '--params-file', str(REAL_CELL), '-p', 'resolution:=VGA',
         '-r', '/forward_position_controller/commands:='
         '/forward_command_controller_position/commands'],
        stdout=sim_log, stderr=subprocess.STDOUT, preexec_fn=supervised_child)
    out_path = tmp_path / 'cell.out'
    seen = set()
    cell = None
    try:
        with open(out_path, 'w') as out:
            # The simulator's start (PyBullet, the taught pair) takes seconds on a loaded
            # machine: the check waits for its topics that long.
            cell = ibvs_cell(tmp_path, '-p', 'use_sim_time:=true', '--check-timeout', '180',
                             stdout=out)
        deadline = time.monotonic() + 300.0
        while time.monotonic() < deadline:
            assert cell.poll() is None, (out_path.read_text(), cell.stderr.read())
            seen.update(ProcTools.descendants(cell.pid))
            text = out_path.read_text()
            if 'frames used' in text and 'servo 0 NO_WARNING' in text:
                break
            time.sleep(0.5)
        seen.update(ProcTools.descendants(cell.pid))
        yield cell, out_path, seen
        assert sim.poll() is None  # the stand-in for the cell is not ibvs cell's to stop
    finally:
        if cell is not None and cell.poll() is None:
            cell.kill()
            cell.wait()
        if sim.poll() is None:
            os.killpg(sim.pid, signal.SIGKILL)
            sim.wait()
        for pid in seen:
            if ProcTools.alive(pid):
                os.kill(pid, signal.SIGKILL)
        sim_log.close()


def node_pids(seen):
    """Return {node: pids whose command line names it} of the cell's nodes."""
    return {name: [p for p in seen if name in ProcTools.cmdline(p)] for name in CELL_NODES}


@pytest.mark.slow
def test_against_the_simulator_it_reports_and_one_sigint_stops_all(cell_under_way):
    cell, out_path, seen = cell_under_way
    text = out_path.read_text()
    assert 'started feature_node' in text, text
    assert '] servo' in text and 'frames used' in text, text
    nodes = node_pids(seen)
    assert all(nodes.values()), nodes
    assert not any('sim_node' in ProcTools.cmdline(p) for p in seen)
    # The joint controller commands abb_ros2's controller by remapping alone.
    assert any('/forward_position_controller/commands:='
               '/forward_command_controller_position/commands' in ProcTools.cmdline(p)
               for p in nodes['joint_controller_node'])
    os.kill(cell.pid, signal.SIGINT)
    assert cell.wait(60.0) == 0, (out_path.read_text(), cell.stderr.read())
    text = out_path.read_text()
    assert 'stopped: feature_node exit 0' in text, text
    leftovers = [p for p in seen if ProcTools.alive(p)]
    assert not leftovers, [ProcTools.cmdline(p) for p in leftovers]


@pytest.mark.slow
def test_a_node_that_dies_ends_the_session_and_the_others_stop(cell_under_way):
    cell, out_path, seen = cell_under_way
    victim = node_pids(seen)['feature_node']
    assert victim, out_path.read_text()
    os.kill(victim[0], signal.SIGKILL)
    assert cell.wait(60.0) == 3, out_path.read_text()
    err = cell.stderr.read()
    assert 'node feature_node exited with code -9' in err, err
    leftovers = [p for p in seen if ProcTools.alive(p)]
    assert not leftovers, [ProcTools.cmdline(p) for p in leftovers]


@pytest.mark.slow
def test_a_second_commander_is_named_on_the_status_line_and_held_on_until_it_goes(
        cell_under_way, context):
    """Acceptance: a rogue publisher on the controller's command topic during the rehearsal."""
    from ibvs_common import contract
    from rclpy.node import Node
    from std_msgs.msg import Float64MultiArray
    cell, out_path, _ = cell_under_way
    command = '/forward_command_controller_position/commands'
    named = f'servo 16 HOLD_SECOND_PUBLISHER (second publisher) | second publisher on {command}'
    rogue = Node('rogue', context=context)
    try:
        rogue.create_publisher(Float64MultiArray, command, contract.RELIABLE)  # sends nothing
        start = len(out_path.read_text())
        deadline = time.monotonic() + 120.0  # a hang guard only
        while named not in out_path.read_text()[start:]:
            assert time.monotonic() < deadline and cell.poll() is None, \
                out_path.read_text()[start:]
            time.sleep(0.1)
        assert ': /rogue (seen by ' in out_path.read_text()[start:]
    finally:
        rogue.destroy_node()
    start = len(out_path.read_text())
    deadline = time.monotonic() + 120.0
    while not any('] servo 0 NO_WARNING' in line and 'seen by' not in line
                  for line in out_path.read_text()[start:].splitlines()):
        assert time.monotonic() < deadline and cell.poll() is None, out_path.read_text()[start:]
        time.sleep(0.1)
    os.kill(cell.pid, signal.SIGINT)
    assert cell.wait(60.0) == 0, out_path.read_text()


def _sim(installed_workspace, log, *params):
    """Start sim_node as the cell (real_cell.yaml at VGA; the simulator teaches nothing)."""
    return subprocess.Popen(
        [str(Path(installed_workspace) / 'lib' / 'ibvs_sim' / 'sim_node'), '--ros-args',
         '--params-file', str(REAL_CELL), '-p', 'resolution:=VGA',
         '-p', 'target_features_source:=model', *params],
        stdout=log, stderr=subprocess.STDOUT, preexec_fn=supervised_child)


def _stop(proc):
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(30.0)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def _pose_errors(text):
    """Return the position errors (mm) of the status lines of ``text``, in order."""
    return [float(m.group(1)) for m in re.finditer(r'\| pose error ([0-9.]+) mm', text)]


@pytest.mark.slow
def test_the_rehearsal_taught_by_ibvs_teach_converges_and_leaves_a_bag_ibvs_analyse_reads(
        installed_workspace, tmp_path):
    """
    Acceptance: docs/real_cell.md's rehearsal, ibvs teach then ibvs cell against sim_node.

    The status line shows the image and pose errors; the session is stopped (one SIGINT, as
    the operator does) once its pose error has stayed within 1 mm for ten lines; its bag
    then ends within the success criterion (1 mm, 0.5 deg) against the true pose taught.
    """
    log = open(tmp_path / 'sim.log', 'w')
    sim = _sim(installed_workspace, log, '-p', 'start_at_target:=true',
               '-p', 'min_command_publishers:=0')
    try:
        teach = subprocess.run([sys.executable, '-m', 'ibvs_experiments.cli', 'teach', '-o',
                                str(tmp_path / 'teach'), '--timeout', '300'],
                               capture_output=True, text=True, timeout=400)
    finally:
        _stop(sim)
    assert teach.returncode == 0, (teach.stdout, teach.stderr)
    assert 'target_position: [' in teach.stdout
    sim = _sim(installed_workspace, log, '-r', '/forward_position_controller/commands:='
               '/forward_command_controller_position/commands')
    out_path = tmp_path / 'cell.out'
    cell = None
    try:
        with open(out_path, 'w') as out:
            cell = ibvs_cell(tmp_path, '--teach', str(tmp_path / 'teach'), '-p',
                             'use_sim_time:=true', '--check-timeout', '180', stdout=out)
        deadline = time.monotonic() + 900.0  # a hang guard: a loaded machine is slow
        while True:
            assert cell.poll() is None, (out_path.read_text(), cell.stderr.read())
            errors = _pose_errors(out_path.read_text())
            if len(errors) >= 10 and max(errors[-10:]) < 1.0:
                break
            assert time.monotonic() < deadline, out_path.read_text()[-3000:]
            time.sleep(1.0)
        text = out_path.read_text()
        assert re.search(r'\| image error [0-9.]+ px \| pose error', text), text[-2000:]
        os.kill(cell.pid, signal.SIGINT)
        assert cell.wait(120.0) == 0, (out_path.read_text(), cell.stderr.read())
    finally:
        if cell is not None and cell.poll() is None:
            cell.kill()
            cell.wait()
        _stop(sim)
        log.close()
    bag = tmp_path / 'cell' / 'bag'
    analysed = subprocess.run([sys.executable, '-m', 'ibvs_experiments.cli', 'analyse',
                               str(bag)], capture_output=True, text=True, timeout=600)
    assert analysed.returncode == 0, (analysed.stdout, analysed.stderr)
    metrics = json.loads((tmp_path / 'cell' / 'metrics.json').read_text())
    assert metrics['target_source'] == 'teach'
    assert metrics['success'], metrics
