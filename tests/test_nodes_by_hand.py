"""
The nodes started by hand as docs/running.md says: they tell how they get on, and stop.

Started by hand, the nodes must say how they get on, stop the simulation at the scenario's
duration, and all stop at Ctrl-C, not only the foreground node. Here the two
shell functions of docs/running.md (``ibvs_nodes``, ``ibvs_nodes_stop``), taken from the
page itself, start the graph in bash with job control, as an interactive shell has it (and
without the ``ros2`` CLI, as this repository's venv has it), with
``-p duration_s:=0.3``; once the simulator says it stopped at 0.3 s and every node has
logged a progress line, ``ibvs_nodes_stop`` must end every node with exit code 0 and leave
no process behind.
"""

import os
from pathlib import Path
import re
import subprocess
import time

import pytest

ROOT = Path(__file__).resolve().parents[1]
RUNNING = ROOT / 'docs' / 'running.md'
BLOCK = re.compile(r'^```bash\n(.*?)^```', re.MULTILINE | re.DOTALL)
PAPER_NODES = ('sim_node', 'feature_node', 'adaptive_feedback_node', 'feedforward_node',
               'joint_controller_node')
#: Every node ibvs_nodes starts: each logs its progress.
LOGGING = PAPER_NODES + ('viz_node', 'robot_state_node')
DURATION_S = 0.3


def functions_block():
    """Return the bash block of docs/running.md that defines ibvs_nodes."""
    blocks = [b for b in BLOCK.findall(RUNNING.read_text()) if 'ibvs_nodes()' in b]
    assert len(blocks) == 1, 'docs/running.md: one bash block defines ibvs_nodes'
    assert 'ibvs_nodes_stop()' in blocks[0]
    return blocks[0]


def test_the_docs_define_both_functions():
    block = functions_block()
    for node in PAPER_NODES:
        assert f'/{node}' in block, node


@pytest.mark.slow
def test_nodes_started_by_hand_log_progress_stop_at_duration_and_stop_together(
        installed_workspace, tmp_path):
    script = (f'set -m\n{functions_block()}\n'
              f'ibvs_nodes {DURATION_S} ros2_ws/src/ibvs_bringup/config/scenario1.yaml\n'
              'echo "pids:" $(jobs -p)\nread -r _\nibvs_nodes_stop\n')
    log = tmp_path / 'nodes.log'
    env = {k: v for k, v in os.environ.items() if k != 'PYTEST_XDIST_WORKER'}
    env['PATH'] = os.pathsep.join(  # the functions' branch without the ros2 CLI
        p for p in env['PATH'].split(os.pathsep) if not (Path(p) / 'ros2').exists())
    with open(log, 'w') as out:
        shell = subprocess.Popen(['bash', '-c', script], cwd=ROOT, env=env, stdout=out,
                                 stderr=subprocess.STDOUT, stdin=subprocess.PIPE, text=True)
    stopped = f'[sim_node]: stopped at t = {DURATION_S:.3f} s'
    pgids = []
    try:
        deadline = time.monotonic() + 240.0
        while time.monotonic() < deadline:
            text = log.read_text(errors='replace')
            if stopped in text and all(f'[{n}]: progress: ' in text for n in LOGGING):
                break
            assert shell.poll() is None, text[-3000:]
            time.sleep(0.5)
        text = log.read_text(errors='replace')
        assert stopped in text, text[-3000:]
        pgids = [int(p) for p in re.search(r'^pids: (.*)$', text, re.MULTILINE).group(1).split()]
        assert len(pgids) == len(LOGGING)
        for node in LOGGING:
            assert f'[{node}]: progress: ' in text, f'{node} logged no progress:\n{text[-3000:]}'
        # The simulator went no further than its duration, and said where it stands.
        assert re.search(rf'\[sim_node\]: progress: t = {DURATION_S:.3f} s of {DURATION_S:g} '
                         r's \(step 300\), stopped at duration_s', text) or \
            re.search(rf'\[sim_node\]: progress: t = 0\.\d+ s of {DURATION_S:g} s', text), text
        assert f't = {DURATION_S + 0.001:.3f} s' not in text
        shell.stdin.write('stop\n')
        shell.stdin.flush()
        assert shell.wait(60.0) == 0
        # Job control reports each job's end: 'Done' is exit code 0 ('Exit N', 'Killed',
        # 'Interrupt' otherwise).
        ends = re.findall(r'^\[\d+\][+-]? +(\w+)', log.read_text(errors='replace'),
                          re.MULTILINE)
        assert ends == ['Done'] * len(pgids), ends
    finally:
        if shell.poll() is None:
            if not pgids:  # failed before reading them: the nodes must not outlive the test
                found = re.search(r'^pids: (.*)$', log.read_text(errors='replace'),
                                  re.MULTILINE)
                pgids = [int(p) for p in found.group(1).split()] if found else []
            for pgid in pgids:
                try:
                    os.killpg(pgid, 9)
                except ProcessLookupError:
                    pass
            shell.kill()
            shell.wait()
    for pgid in pgids:  # nothing left of any node's process group
        with pytest.raises(ProcessLookupError):
            os.killpg(pgid, 0)
