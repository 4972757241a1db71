"""Killing a node mid-run: the runner stops, names the node and its exit code, leaves nothing."""

import signal


def test_runner_reports_a_dead_node_and_leaves_no_process(installed_workspace, signalled_run):
    # Once the simulator runs, the run is really under way; let the graph take a few steps.
    code, out, err = signalled_run([], lambda log: log.exists(), signal.SIGKILL, 60.0,
                                   settle_s=2.0)
    assert code == 3, (out, err)
    # The feature node runs in the simulator's process, which the message names with it.
    assert 'node lockstep (nodes feature_node, ' in err, err
    assert f'code {-signal.SIGKILL}' in err, err
