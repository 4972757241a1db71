"""Fixtures of the cross-package tests: the shared ones, the installed workspace, /proc."""

import os

from ibvs_common.testing import context  # noqa: F401 (the shared fixture)
import pytest


@pytest.fixture(scope='session')
def installed_workspace():
    """Skip unless the workspace is built and sourced (make test does both)."""
    prefix = os.environ.get('AMENT_PREFIX_PATH', '')
    if not prefix:
        pytest.skip('AMENT_PREFIX_PATH is empty: run through make test (colcon build + source)')
    return prefix.split(os.pathsep)[0]


class ProcTools:
    """Process inspection through /proc (Linux), for tests that must leave nothing behind."""

    @staticmethod
    def children(pid):
        """Return the PIDs of the direct children of ``pid``."""
        out = []
        try:
            tasks = os.listdir(f'/proc/{pid}/task')
        except FileNotFoundError:
            return out
        for task in tasks:
            try:
                with open(f'/proc/{pid}/task/{task}/children') as f:
                    out += [int(c) for c in f.read().split()]
            except FileNotFoundError:
                pass
        return out

    @classmethod
    def descendants(cls, pid):
        """Return every PID below ``pid``."""
        out, todo = [], [pid]
        while todo:
            kids = cls.children(todo.pop())
            out += kids
            todo += kids
        return out

    @staticmethod
    def alive(pid):
        """Return True while ``pid`` exists and is not a zombie."""
        try:
            with open(f'/proc/{pid}/stat') as f:
                return f.read().rsplit(')', 1)[-1].split()[0] != 'Z'
        except FileNotFoundError:
            return False

    @staticmethod
    def cmdline(pid):
        """Return the command line of ``pid`` as one string ('' if gone)."""
        try:
            with open(f'/proc/{pid}/cmdline', 'rb') as f:
                return f.read().replace(b'\0', b' ').decode()
        except FileNotFoundError:
            return ''


@pytest.fixture
def proc_tools():
    """Return the /proc helpers."""
    return ProcTools
