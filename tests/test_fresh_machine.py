"""
On a machine without what the build or a run needs, ``make`` stops at once and names it.

Without cmake, ``make demo`` would create the venv and then fail in ``colcon build``; without
libEGL or Mesa, ``ibvs run`` would fail after the venv and the build ("no standalone EGL
OpenGL 3.3 context"). ``tools/check_system.sh`` runs first in the Makefile's venv and build
recipes. Here it runs with a PATH of links to every program of this machine but those hidden,
with a linker cache that lacks libEGL (an ``ldconfig`` first on the PATH that prints the real
cache without it), and with Mesa's and glvnd's own search variables set to an empty folder.
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


def ldconfig_without(tmp_path, soname):
    """Return a folder whose ``ldconfig`` prints this machine's linker cache without ``soname``."""
    real = shutil.which('ldconfig', path=os.environ['PATH'] + ':/usr/sbin:/sbin')
    folder = tmp_path / 'fake_ldconfig'
    folder.mkdir()
    fake = folder / 'ldconfig'
    fake.write_text(f'#!/bin/bash\n{real} "$@" | grep -v "^[[:space:]]*{re.escape(soname)} "\n')
    fake.chmod(0o755)
    return str(folder)


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


def python311():
    """Return this Python if it is 3.11 (what the check wants), else skip the test."""
    if sys.version_info[:2] != (3, 11):
        pytest.skip('not Python 3.11')
    return sys.executable


@pytest.mark.skipif(shutil.which('ldconfig', path=os.environ['PATH'] + ':/usr/sbin:/sbin')
                    is None, reason='no linker cache (ldconfig) on this machine')
def test_the_check_names_libegl1_when_the_linker_cache_lacks_libegl(tmp_path):
    python = python311()
    if check(os.environ['PATH'], python) != (0, ''):
        pytest.skip('this machine lacks part of what a run needs itself')
    path = ldconfig_without(tmp_path, 'libEGL.so.1') + os.pathsep + os.environ['PATH']
    code, err = check(path, python)
    assert code == 1
    assert 'no libEGL.so.1' in err and '(Debian/Ubuntu package: libegl1)' in err
    assert err.rstrip().endswith('sudo apt-get install libegl1')
    # A libEGL.so.1 in LD_LIBRARY_PATH is one dlopen finds.
    libs = tmp_path / 'lib'
    libs.mkdir()
    (libs / 'libEGL.so.1').touch()
    assert check(path, python, LD_LIBRARY_PATH=str(libs)) == (0, '')


def test_the_check_names_mesa_when_its_driver_and_vendor_file_are_not_found(tmp_path):
    python = python311()
    if check(os.environ['PATH'], python) != (0, ''):
        pytest.skip('this machine lacks part of what a run needs itself')
    empty = tmp_path / 'empty'
    empty.mkdir()
    code, err = check(os.environ['PATH'], python, LIBGL_DRIVERS_PATH=str(empty),
                      __EGL_VENDOR_LIBRARY_DIRS=str(empty))
    assert code == 1
    assert 'swrast_dri.so' in err and '(Debian/Ubuntu package: libgl1-mesa-dri)' in err
    assert 'Mesa EGL vendor file' in err and '(Debian/Ubuntu package: libegl-mesa0)' in err
    assert err.rstrip().endswith('sudo apt-get install libegl-mesa0 libgl1-mesa-dri')
    # Where they are: a driver in LIBGL_DRIVERS_PATH, a vendor file named by glvnd's list.
    (empty / 'swrast_dri.so').touch()
    (empty / '50_mesa.json').write_text('{}')
    assert check(os.environ['PATH'], python, LIBGL_DRIVERS_PATH=str(empty),
                 __EGL_VENDOR_LIBRARY_FILENAMES=str(empty / '50_mesa.json')) == (0, '')


def test_the_readme_install_line_brings_every_package_the_check_names():
    named = set(re.findall(r'\bneed ([a-z0-9][a-z0-9.+-]*) "', CHECK.read_text()))
    assert {'python3', 'cmake', 'libegl1', 'libegl-mesa0', 'libgl1-mesa-dri'} <= named
    readme = (ROOT / 'README.md').read_text()
    line = set(re.search(r'`sudo apt-get install ([^`]*)`', readme).group(1).split())
    # Dependencies of Debian's and Ubuntu's packages: python3 of python3-venv, libegl-mesa0
    # of libegl1.
    comes_with = {'python3': 'python3-venv', 'libegl-mesa0': 'libegl1'}
    assert {comes_with.get(name, name) for name in named} <= line, named - line
    dockerfile = (ROOT / 'docker' / 'Dockerfile').read_text()
    assert all(package in dockerfile for package in ('libegl1', 'libgl1-mesa-dri'))


def test_the_makefile_checks_before_the_venv_and_before_the_build():
    makefile = (ROOT / 'Makefile').read_text()
    for target in (r'\$\(VENV_STAMP\)', r'\$\(BUILD_STAMP\)'):
        recipe = re.search(rf'^{target}:.*\n\t(.*)', makefile, re.MULTILINE)
        assert recipe and recipe.group(1) == 'tools/check_system.sh $(PYTHON)', target
    readme = (ROOT / 'README.md').read_text()
    assert 'sudo apt-get install make python3-venv python3-dev cmake gcc g++ libegl1 ' \
        'libgl1-mesa-dri' in readme
