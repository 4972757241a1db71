"""
The workspace's tf2_msgs never shadows an underlay's: where one has it, it builds nothing.

``ros2_ws/src/tf2_msgs/CMakeLists.txt`` asks find_package for tf2_msgs outside its own
install prefix (CMake's prefixes and AMENT_PREFIX_PATH). Here it is configured with a fake
underlay (a folder holding ``share/tf2_msgs/cmake/tf2_msgsConfig.cmake``) and installed;
and with a tf2_msgs config in its own install prefix only, which is no underlay (an earlier
build of the same workspace, the prefix sourced).
"""

import os
from pathlib import Path
import shutil
import subprocess

import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / 'ros2_ws' / 'src' / 'tf2_msgs'

pytestmark = pytest.mark.skipif(shutil.which('cmake') is None, reason='no cmake')


def fake_prefix(folder, config_text='# a tf2_msgs of an underlay\n'):
    """Return ``folder`` made a prefix whose tf2_msgs config holds ``config_text``."""
    config = folder / 'share' / 'tf2_msgs' / 'cmake'
    config.mkdir(parents=True)
    (config / 'tf2_msgsConfig.cmake').write_text(config_text)
    return folder


def configure(tmp_path, install, **env):
    """Configure the package into tmp_path/build; return (exit code, output)."""
    done = subprocess.run(
        ['cmake', '-S', str(SOURCE), '-B', str(tmp_path / 'build'),
         f'-DCMAKE_INSTALL_PREFIX={install}', '-DBUILD_TESTING=OFF'],
        capture_output=True, text=True, timeout=300,
        env={**{k: v for k, v in os.environ.items()
                if k not in ('CMAKE_PREFIX_PATH', 'AMENT_PREFIX_PATH')}, **env})
    return done.returncode, done.stdout + done.stderr


@pytest.mark.parametrize('variable', ['CMAKE_PREFIX_PATH', 'AMENT_PREFIX_PATH'])
def test_an_underlays_tf2_msgs_makes_the_package_install_nothing_of_its_own(tmp_path,
                                                                            variable):
    underlay = fake_prefix(tmp_path / 'underlay')
    install = tmp_path / 'install'
    code, out = configure(tmp_path, install, **{variable: str(underlay)})
    assert code == 0, out
    assert f"tf2_msgs: the underlay's ({underlay}/share/tf2_msgs/cmake) is used" in out
    done = subprocess.run(['cmake', '--install', str(tmp_path / 'build')],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stdout + done.stderr
    installed = sorted(str(p.relative_to(install)) for p in install.rglob('*') if p.is_file())
    # Only colcon's environment hooks, empty: no CMake config, no ament index entry, no
    # message, no Python module that would hide the underlay's.
    assert installed == [f'share/tf2_msgs/local_setup.{ext}'
                         for ext in sorted(('bash', 'dsv', 'ps1', 'sh', 'zsh'))]
    assert all((install / name).read_text() == '' for name in installed)


@pytest.mark.skipif(not os.environ.get('VIRTUAL_ENV'), reason='needs the venv (rosidl)')
def test_a_tf2_msgs_in_its_own_install_prefix_is_no_underlay(tmp_path):
    # Loading that config would fail the configure: it must not even be read.
    install = fake_prefix(tmp_path / 'install', 'message(FATAL_ERROR "own config read")\n')
    code, out = configure(tmp_path, install, CMAKE_PREFIX_PATH=str(install),
                          AMENT_PREFIX_PATH=os.pathsep.join((os.environ['VIRTUAL_ENV'],
                                                             str(install))))
    assert code == 0, out
    assert 'tf2_msgs: no underlay has it; building TFMessage' in out
