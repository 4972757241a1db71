"""
Helpers for tests of plain code (the lockstep rules): arrival orders, runs without rclpy.

Imports neither rclpy nor pytest, so that a test module of plain code that uses it can be
run in a process where rclpy is never imported (:func:`run_without_rclpy`).
"""

import importlib.util
import os
from pathlib import Path
import random
import subprocess
import sys
from typing import Iterable, List, TypeVar, Union

T = TypeVar('T')


def interleave(rng: random.Random, *streams: Iterable[T]) -> List[T]:
    """
    Interleave ``streams`` at random, each kept in its own order.

    One publisher per topic on a reliable connection delivers its messages in order, but
    the topics' messages reach a node in any interleaving: this draws one.

    Parameters
    ----------
    rng : random.Random
        The draws (seeded by the test, so that a failure repeats).
    *streams : iterable
        The messages of each topic, in their order.

    Returns
    -------
    list
        Every message of every stream once.

    """
    pending = [list(s) for s in streams]
    out: List[T] = []
    while any(pending):
        stream = rng.choice([s for s in pending if s])
        out.append(stream.pop(0))
    return out


def run_without_rclpy(test_file: Union[str, Path], caller: str) -> int:
    """
    Run every ``test_*`` function of ``test_file`` but ``caller`` in a process without rclpy.

    The functions must take no fixtures. The child loads the file by its path (not as part
    of a package) with this process's ``sys.path``, runs them, and fails if ``rclpy`` was
    imported on the way; this process asserts that the child passed.

    Parameters
    ----------
    test_file : str or Path
        The test module (``__file__`` of the caller).
    caller : str
        The name of the calling test function, left out (it would recurse).

    Returns
    -------
    int
        How many test functions ran.

    """
    have_rclpy = importlib.util.find_spec('rclpy') is not None
    code = f"""
import importlib.util, sys
spec = importlib.util.spec_from_file_location('plain_tests', {str(Path(test_file))!r})
module = importlib.util.module_from_spec(spec)
spec.loader.exec_module(module)
names = [n for n in sorted(vars(module)) if n.startswith('test_') and n != {caller!r}]
for name in names:
    getattr(module, name)()
assert (importlib.util.find_spec('rclpy') is not None) == {have_rclpy}
assert 'rclpy' not in sys.modules, 'rclpy was imported'
print(len(names), 'tests without rclpy')
"""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    done = subprocess.run([sys.executable, '-c', code], env=env, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout.endswith(' tests without rclpy\n'), done.stdout
    return int(done.stdout.split()[-4])
