"""
On a machine without what the build needs, ``make`` stops at once and names what to install.

Issue 37: with cmake off the PATH, ``make demo`` created the venv and then failed in
``colcon build`` ("Could not find 'cmake' executable ... 1 package failed: tf2_msgs").
``tools/check_system.sh`` runs first in the Makefile's venv and build recipes; here it runs
with a PATH of links to every program of this machine but those hidden.
"""

import os
from pathlib import Path
import re
import shutil
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parents[1]
CHECK = ROOT / 'tools' / 'check_system.sh'


def shim_path(tmp_path, hidden):
    """Return a PATH of one folder linking every program on this PATH but ``hidden``."""
    shim = tmp_path / 'bin'
    shim.mkdir()
    for folder in os.environ['PATH'].split(os.pathsep):
        if not os.path.isdir(folder):
            continue
        for entry in os.scandir(folder):
            if entry.name not in hidden and not (shim / entry.name).exists() and \
                    os.access(entry.path, os.X_OK):
                (shim / entry.name).symlink_to(entry.path)
    return str(shim)


def check(path, *args, **env):
    """Run the check with ``PATH=path``; return (exit code, stderr)."""
    done = subprocess.run(['bash', str(CHECK), *args], capture_output=True, text=True,
                          timeout=10, env={'PATH': path, 'HOME': os.environ.get('HOME', '/'),
                                           **env})
    return done.returncode, done.stderr


@pytest.mark.skipif(not all(map(shutil.which, ('cmake', 'cc', 'c++'))),
                    reason='this machine lacks cmake or a compiler itself')
def test_the_check_names_the_debian_package_of_each_missing_piece(tmp_path):
    python = sys.executable if sys.version_info[:2] == (3, 11) else None
    if python is None:
        pytest.skip('not Python 3.11')
    assert check(os.environ['PATH'], python) == (0, '')
    path = shim_path(tmp_path, {'cmake', 'cc', 'c++', 'gcc', 'g++'})
    code, err = check(path, python)
    assert code == 1
    assert "no 'cmake' on the PATH (Debian/Ubuntu package: cmake)" in err
    assert "no C compiler 'cc'" in err and "no C++ compiler 'c++'" in err
    assert err.rstrip().endswith('sudo apt-get install cmake g++ gcc')
    code, err = check(os.environ['PATH'], 'no-such-python3')
    assert code == 1 and "no 'no-such-python3' on the PATH" in err and 'python3' in err
    code, err = check(os.environ['PATH'], python, CXX='no-such-c++')
    assert code == 1 and "no C++ compiler 'no-such-c++'" in err and err.count('\n') == 3


def test_the_makefile_checks_before_the_venv_and_before_the_build():
    makefile = (ROOT / 'Makefile').read_text()
    for target in (r'\$\(VENV_STAMP\)', r'\$\(BUILD_STAMP\)'):
        recipe = re.search(rf'^{target}:.*\n\t(.*)', makefile, re.MULTILINE)
        assert recipe and recipe.group(1) == 'tools/check_system.sh $(PYTHON)', target
    readme = (ROOT / 'README.md').read_text()
    assert 'sudo apt-get install make python3-venv python3-dev cmake gcc g++' in readme
