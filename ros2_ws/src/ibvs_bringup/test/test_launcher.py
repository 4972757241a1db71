"""The launcher's parts without a graph: its one supervising loop, its domain, its imports."""

import ast
from pathlib import Path

from ibvs_bringup import domains, launcher
import pytest

PACKAGE = Path(__file__).resolve().parents[1] / 'ibvs_bringup'


class _Executor:
    """Counts the spins and the futures it was given."""

    def __init__(self):
        self.futures = []

    def spin_until_future_complete(self, future, timeout_sec):
        self.futures.append(future)


class _Interrupt:

    def __init__(self, after):
        self.after, self.looks = after, 0

    def is_set(self):
        self.looks += 1
        return self.looks > self.after


def test_the_loop_returns_the_first_end_its_tick_gives_and_spins_before_each_look():
    executor, looks = _Executor(), []

    def tick():
        looks.append(len(executor.futures))
        return 'ended' if len(looks) == 3 else None

    assert launcher.supervise(executor, tick) == 'ended'
    assert looks == [1, 2, 3]
    # A future of its own each spin: rclpy adds a callback to it at every call.
    assert len({id(f) for f in executor.futures}) == len(executor.futures)


def test_a_deferred_sigint_ends_the_loop_between_two_spins_not_inside_a_tick():
    executor, ticks = _Executor(), []
    with pytest.raises(KeyboardInterrupt):
        launcher.supervise(executor, lambda: ticks.append(1), interrupt=_Interrupt(after=2))
    assert len(ticks) == 2 and len(executor.futures) == 3


def test_a_cells_default_domain_is_taken_only_where_ros_domain_id_is_unset(monkeypatch):
    for name in (domains.DOMAIN_ENV, domains.HELD_ENV):
        monkeypatch.setenv(name, '')  # put back as it was after the test
        monkeypatch.delenv(name)
    said = []
    with launcher.held_domain(said.append, default=domains.SAFE_RANGE[1]) as domain:
        assert domain == domains.SAFE_RANGE[1]
    assert said == [f'  ROS_DOMAIN_ID {domain} (set by ROS_DOMAIN_ID)']
    with launcher.held_domain(default=domains.SAFE_RANGE[0]) as again:
        assert again == domain  # set now: the default is not taken


def _imported(path):
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0:
            yield node.module


def test_the_launcher_package_imports_nothing_of_the_experiments_or_their_analysis():
    found = {f'{path.name}: {name}' for path in PACKAGE.glob('*.py')
             for name in _imported(path) if name.split('.')[0] == 'ibvs_experiments'}
    assert found == set()
