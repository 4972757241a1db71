"""Process inspection through /proc (Linux), for tests that must leave nothing behind."""

import os
from typing import List


class ProcTools:
    """Children, descendants, liveness and command lines of processes, read from /proc."""

    @staticmethod
    def children(pid: int) -> List[int]:
        """Return the PIDs of the direct children of ``pid``."""
        out: List[int] = []
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
    def descendants(cls, pid: int) -> List[int]:
        """Return every PID below ``pid``."""
        out: List[int] = []
        todo = [pid]
        while todo:
            kids = cls.children(todo.pop())
            out += kids
            todo += kids
        return out

    @staticmethod
    def alive(pid: int) -> bool:
        """Return True while ``pid`` exists and is not a zombie."""
        try:
            with open(f'/proc/{pid}/stat') as f:
                return f.read().rsplit(')', 1)[-1].split()[0] != 'Z'
        except FileNotFoundError:
            return False

    @staticmethod
    def cmdline(pid: int) -> str:
        """Return the command line of ``pid`` as one string ('' if gone)."""
        try:
            with open(f'/proc/{pid}/cmdline', 'rb') as f:
                return f.read().replace(b'\0', b' ').decode()
        except FileNotFoundError:
            return ''
