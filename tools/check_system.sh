#!/bin/bash
# What `make` needs of the system before it creates .venv and builds ros2_ws, checked first,
# each missing piece named with the Debian package that brings it (issue 37):
#   - Python 3.11 with venv (ensurepip) and its headers: the ROS wheels are cp311 only, and
#     the interface package ros2_ws/src/tf2_msgs builds a Python C extension;
#   - CMake and a C and a C++ compiler: colcon builds tf2_msgs with CMake (rosidl generates
#     C and C++ type support).
# Usage: tools/check_system.sh [PYTHON]   (default python3; the Makefile passes $(PYTHON)).
# Prints nothing and exits 0 when all is there; else one line per missing piece and the
# apt-get line that installs them, and exits 1.
python=${1:-python3}
missing=()
packages=()

need() {  # need PACKAGE WHAT
    missing+=("  $2 (Debian/Ubuntu package: $1)")
    packages+=("$1")
}

if ! command -v "$python" > /dev/null 2>&1; then
    need python3 "no '$python' on the PATH (Python 3.11; another one: make PYTHON=python3.11)"
else
    version=$("$python" -c 'import sys; print("%d.%d" % sys.version_info[:2])' 2>/dev/null)
    if [ "$version" != 3.11 ]; then
        need python3 "'$python' is Python ${version:-?}, the ROS 2 wheels need 3.11 (Debian 12's python3; another one: make PYTHON=python3.11)"
    else
        "$python" -c 'import ensurepip, venv' > /dev/null 2>&1 ||
            need python3-venv "'$python -m venv' cannot install pip (no ensurepip)"
        "$python" -c 'import os, sysconfig, sys
sys.exit(not os.path.isfile(os.path.join(sysconfig.get_paths()["include"], "Python.h")))' ||
            need python3-dev "no Python.h for '$python' (the Python headers)"
    fi
fi
command -v cmake > /dev/null 2>&1 || need cmake "no 'cmake' on the PATH"
command -v "${CC:-cc}" > /dev/null 2>&1 || need gcc "no C compiler '${CC:-cc}' on the PATH"
command -v "${CXX:-c++}" > /dev/null 2>&1 || need g++ "no C++ compiler '${CXX:-c++}' on the PATH"

if [ ${#missing[@]} -gt 0 ]; then
    echo "error: this machine lacks what the build needs:" >&2
    printf '%s\n' "${missing[@]}" >&2
    echo "install them, then run make again: sudo apt-get install $(printf '%s\n' "${packages[@]}" | sort -u | paste -sd ' ')" >&2
    exit 1
fi
