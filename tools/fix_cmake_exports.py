"""
Point the venv's rosidl Python CMake exports at this machine's Python and numpy headers.

The ``ros-jazzy-*`` message wheels ship
``share/<pkg>/cmake/export_<pkg>__rosidl_generator_pyExport.cmake`` files that name the
include directories of the machine the wheels were built on
(``/opt/python/cp311-cp311/...``); CMake stops on a directory that does not exist when a
workspace interface package (``ros2_ws/src/tf2_msgs``) depends on such a package.
This rewrites that one property to ``sysconfig.get_paths()['include']`` and
``numpy.get_include()`` of the interpreter that runs it (the venv's). Idempotent; the
Makefile runs it after every fresh venv (see ../shared/notes/interface-packages.md).

Usage: ``.venv/bin/python tools/fix_cmake_exports.py`` (prints how many files it changed).
"""

from pathlib import Path
import re
import sys
import sysconfig

import numpy

_PROPERTY = re.compile(r'INTERFACE_INCLUDE_DIRECTORIES "[^"]*"')


def fix(prefix=sys.prefix):
    """Rewrite the include directories of every rosidl Python export under ``prefix``."""
    wanted = (f'INTERFACE_INCLUDE_DIRECTORIES '
              f'"{sysconfig.get_paths()["include"]};{numpy.get_include()}"')
    changed = 0
    for path in Path(prefix, 'share').glob('*/cmake/*__rosidl_generator_pyExport.cmake'):
        text = path.read_text()
        new = _PROPERTY.sub(lambda _: wanted, text)
        if new != text:
            path.write_text(new)
            changed += 1
    return changed


if __name__ == '__main__':
    print(f'fix_cmake_exports: {fix()} rosidl Python export(s) rewritten under {sys.prefix}')
