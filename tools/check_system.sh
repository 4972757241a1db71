#!/bin/bash
# What `make` needs of the system before it creates .venv and builds ros2_ws, checked first,
# and what a run needs of it, each missing piece named with the Debian package that brings it:
#   - Python 3.11 with venv (ensurepip) and its headers: the ROS wheels are cp311 only, and
#     the interface package ros2_ws/src/tf2_msgs builds a Python C extension;
#   - CMake and a C and a C++ compiler: colcon builds tf2_msgs with CMake (rosidl generates
#     C and C++ type support);
#   - libEGL.so.1 (glvnd's, as the renderer opens it: ibvs_sim/gl_renderer.py), Mesa's EGL
#     vendor file and Mesa's software DRI driver (swrast_dri.so, llvmpipe): the context every
#     camera image is drawn on, headless, where no GPU driver offers one. Looked for where the
#     loaders look: the linker cache (ldconfig -p) and LD_LIBRARY_PATH for libEGL.so.1, glvnd's
#     vendor folders (or __EGL_VENDOR_LIBRARY_DIRS / __EGL_VENDOR_LIBRARY_FILENAMES) for the
#     vendor file, Mesa's DRI folders (or LIBGL_DRIVERS_PATH) for the driver.
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

# libEGL.so.1 as dlopen finds a bare soname: LD_LIBRARY_PATH, then the linker cache (ldconfig
# is in /sbin, often not on a user's PATH: searched after the PATH).
egl_found() {
    local dir
    local IFS=:
    for dir in $LD_LIBRARY_PATH; do
        [ -n "$dir" ] && [ -e "$dir/libEGL.so.1" ] && return 0
    done
    PATH="$PATH:/usr/sbin:/sbin" ldconfig -p 2>/dev/null | grep -q '^[[:space:]]*libEGL\.so\.1 '
}
egl_found || need libegl1 "no libEGL.so.1 (the EGL the renderer opens: neither the linker cache, ldconfig -p, nor LD_LIBRARY_PATH has it)"

# Mesa's EGL vendor file (glvnd: the first of its lists that is set is the one it reads).
mesa_vendor_found() {
    local entry
    local IFS=:
    if [ -n "$__EGL_VENDOR_LIBRARY_FILENAMES" ]; then
        for entry in $__EGL_VENDOR_LIBRARY_FILENAMES; do
            case "${entry##*/}" in *mesa*.json) [ -f "$entry" ] && return 0 ;; esac
        done
        return 1
    fi
    for entry in ${__EGL_VENDOR_LIBRARY_DIRS:-/etc/glvnd/egl_vendor.d:/usr/share/glvnd/egl_vendor.d}; do
        compgen -G "$entry/*mesa*.json" > /dev/null && return 0
    done
    return 1
}
mesa_vendor_found || need libegl-mesa0 "no Mesa EGL vendor file (*mesa*.json in glvnd's egl_vendor.d): libEGL has no software device"

# Mesa's software driver: LIBGL_DRIVERS_PATH where set (Mesa then reads only it), else the
# multiarch and the plain library folders.
swrast_found() {
    local dir
    local IFS=:
    for dir in ${LIBGL_DRIVERS_PATH:-$(printf '%s:' /usr/lib/*/dri /usr/lib64/dri /usr/lib/dri)}; do
        [ -e "$dir/swrast_dri.so" ] && return 0
    done
    return 1
}
swrast_found || need libgl1-mesa-dri "no Mesa software DRI driver (swrast_dri.so, llvmpipe) in ${LIBGL_DRIVERS_PATH:-/usr/lib/*/dri}"

if [ ${#missing[@]} -gt 0 ]; then
    echo "error: this machine lacks what the build or a run needs:" >&2
    printf '%s\n' "${missing[@]}" >&2
    echo "install them, then run make again: sudo apt-get install $(printf '%s\n' "${packages[@]}" | sort -u | paste -sd ' ')" >&2
    exit 1
fi
