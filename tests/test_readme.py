"""
The README's commands work as written, and none of them touches ``make demo``'s results.

A README command such as ``ibvs run scenario1 --duration 0.5 --video`` must not write into
``results/scenario1``, over ``make demo``'s metrics. Here every ``bash`` block of the README
runs, as a user would paste it, at the root of a folder that holds the repository's
``.venv`` and ``ros2_ws`` (links) and a ``results/scenario1`` from a ``make demo``-like run
(``ibvs run scenario1 -o results/scenario1 -p actuators:=ideal``, short). Lines that run a
``make`` target are left out (``make demo`` and ``make test`` take minutes; other tests
cover them), and each ``ibvs run`` gets a short ``--duration``; a later line that names the
run's folder is given the folder of the shortened run (:func:`ibvs_experiments.cli.run_folder`).
"""

import argparse
import hashlib
import os
from pathlib import Path
import re
import shlex
import subprocess
import sys

from ibvs_experiments import cli
import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / 'README.md'
#: Sim seconds of each ``ibvs run`` of the README here.
SHORT_S = 0.2
BLOCK = re.compile(r'^```bash\n(.*?)^```', re.MULTILINE | re.DOTALL)
#: What rcl prints when it takes ``-p name:=value`` of sys.argv for a remap rule.
REMAP_WARNING = 'Found remap rule'


def bash_blocks(text):
    """Return the lines of each ``bash`` block of a Markdown text."""
    return [block.splitlines() for block in BLOCK.findall(text)]


def words(line):
    """Return the words of a shell line, without its comment."""
    return shlex.split(line, comments=True)


def shortened(line):
    """
    Return ``line`` with a short ``--duration`` if it is an ``ibvs run``, and its folders.

    Parameters
    ----------
    line : str
        One line of a README block.

    Returns
    -------
    tuple of (str, Path or None, Path or None)
        The line to run, and for an ``ibvs run`` without ``-o`` the folder the README's line
        writes and the one the shortened line writes (else None, None).

    """
    argv = words(line)
    if argv[:2] != ['ibvs', 'run']:
        return line, None, None
    parser = argparse.ArgumentParser(add_help=False)
    parser.add_argument('scenario')
    parser.add_argument('-o', '--out')
    parser.add_argument('--duration', type=float)
    parser.add_argument('-p', '--param', action='append', default=[])
    args, rest = parser.parse_known_args(argv[2:])
    short = [*argv[:2], args.scenario, '--duration', str(SHORT_S)]
    short += [w for p in args.param for w in ('-p', p)] + rest
    if args.out:
        return shlex.join(short + ['-o', args.out]), None, None
    return (shlex.join(short), cli.run_folder(args.scenario, args.param, args.duration),
            cli.run_folder(args.scenario, args.param, SHORT_S))


def script_of(lines):
    """Return a README block as the script to run here, and the run folders it writes."""
    script, renamed, folders = [], {}, []
    for line in lines:
        argv = words(line)
        if not argv or argv[0] == 'make':
            continue
        line, readme_folder, folder = shortened(line)
        for old, new in renamed.items():
            line = line.replace(old, new)
        if folder is not None:
            renamed[str(readme_folder)] = str(folder)
            folders.append(folder)
        script.append(line)
    return '\n'.join(script), folders


def snapshot(folder):
    """Return every file under ``folder``: its size, modification time and SHA-256."""
    return {str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns,
                                         hashlib.sha256(p.read_bytes()).hexdigest())
            for p in sorted(folder.rglob('*')) if p.is_file()}


def test_blocks_are_found_and_runs_shortened():
    blocks = bash_blocks(README.read_text(encoding='utf-8'))
    assert any('make demo' in line for block in blocks for line in block)
    assert any(words(line)[:2] == ['ibvs', 'run'] for block in blocks for line in block
               if words(line))
    line, readme_folder, folder = shortened(
        'ibvs run scenario1 --duration 0.5 -p a:=1 --video  # a comment')
    assert words(line) == ['ibvs', 'run', 'scenario1', '--duration', str(SHORT_S), '-p',
                           'a:=1', '--video']
    assert readme_folder == Path('results/runs/scenario1_a=1_0.5s')
    assert folder == Path(f'results/runs/scenario1_a=1_{SHORT_S:g}s')
    script, folders = script_of(['make demo', 'ibvs run scenario2',
                                 'ibvs analyse results/runs/scenario2/bag'])
    assert script.splitlines()[1] == f'ibvs analyse results/runs/scenario2_{SHORT_S:g}s/bag'
    assert folders == [Path(f'results/runs/scenario2_{SHORT_S:g}s')]


@pytest.mark.slow
def test_readme_blocks_run_and_leave_make_demos_results_alone(installed_workspace, tmp_path):
    for name in ('.venv', 'ros2_ws'):
        (tmp_path / name).symlink_to(ROOT / name)
    env = {**os.environ, 'PYTHONUNBUFFERED': '1'}
    demo = subprocess.run(
        [sys.executable, '-m', 'ibvs_experiments.cli', 'run', 'scenario1', '-o',
         'results/scenario1', '-p', 'actuators:=ideal', '--duration', str(SHORT_S),
         '--no-figures'], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert demo.returncode == 0, demo.stdout + demo.stderr
    before = snapshot(tmp_path / 'results' / 'scenario1')
    assert 'metrics.json' in before
    ran = 0
    for lines in bash_blocks(README.read_text(encoding='utf-8')):
        script, folders = script_of(lines)
        if not script:
            continue
        done = subprocess.run(['bash', '-e', '-o', 'pipefail', '-c', script], cwd=tmp_path,
                              env=env, capture_output=True, text=True, timeout=600)
        output = done.stdout + done.stderr
        assert done.returncode == 0, f'{script}\n{output[-4000:]}'
        assert REMAP_WARNING not in output, output
        for folder in folders:
            assert (tmp_path / folder / 'metrics.json').is_file(), folder
        ran += 1
    assert ran, 'no block of the README ran'
    assert snapshot(tmp_path / 'results' / 'scenario1') == before
