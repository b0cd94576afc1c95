#!/usr/bin/env python3
"""Point the CMake files exported by the ros-jazzy-* wheels at THIS machine's Python.

The ROS 2 Jazzy wheels on PyPI were built in a manylinux container whose Python lives in
/opt/python/cp311-cp311. About 15 of the CMake files they install (the
``export_<pkg>__rosidl_generator_pyExport.cmake`` of every message package) name that
interpreter's include directory and numpy's include directory in
INTERFACE_INCLUDE_DIRECTORIES. CMake refuses imported targets with non-existent paths, so
``colcon build`` of any interface package that depends on them (catheter_interfaces depends
on std_msgs and geometry_msgs) fails with::

    Imported target "std_msgs::std_msgs__rosidl_generator_py" includes non-existent path
      "/opt/python/cp311-cp311/include/python3.11"

This script rewrites, in every ``*.cmake`` file under ``<prefix>/share``:

    /opt/python/cp311-cp311/include/python3.11            -> sysconfig include dir (Python.h)
    /opt/python/cp311-cp311/lib/python3.11/site-packages  -> this venv's site-packages

It is idempotent (a second run finds nothing to change), prints what it changed, and exits
1 when a rewritten path does not exist here (so the build fails now, not later with a
confusing compiler error).

    python scripts/fix_ros_wheel_paths.py [PREFIX]      # PREFIX: the venv (default sys.prefix)
"""
from __future__ import annotations

import pathlib
import sys
import sysconfig

#: prefix of the build container's Python, as the wheels' CMake files name it
WHEEL_PYTHON = '/opt/python/cp311-cp311'


def replacements(prefix: pathlib.Path):
    """[(old, new)] path prefixes, most specific first."""
    ver = f'python{sys.version_info[0]}.{sys.version_info[1]}'
    include = sysconfig.get_paths()['include']
    site = sysconfig.get_paths(vars={'base': str(prefix), 'platbase': str(prefix)})['purelib']
    return [(f'{WHEEL_PYTHON}/include/{ver}', include),
            (f'{WHEEL_PYTHON}/lib/{ver}/site-packages', site)]


def fix(prefix: pathlib.Path, log=print) -> tuple:
    """Rewrite the CMake files under prefix/share; returns (files changed, missing paths)."""
    changed = 0
    missing = set()
    reps = replacements(prefix)
    share = prefix / 'share'
    if not share.is_dir():
        return 0, set()
    for path in sorted(share.glob('*/cmake/*.cmake')):
        try:
            text = path.read_text()
        except (OSError, UnicodeDecodeError):
            continue
        if WHEEL_PYTHON not in text:
            continue
        new = text
        for old, repl in reps:
            new = new.replace(old, repl)
        if new != text:
            path.write_text(new)
            changed += 1
        for line in new.splitlines():
            if 'INTERFACE_INCLUDE_DIRECTORIES' in line and '"' in line:
                for p in line.split('"')[1].split(';'):
                    if p and not p.startswith('$') and not pathlib.Path(p).exists():
                        missing.add(p)
        if WHEEL_PYTHON in new:
            missing.add(f'{path}: still names {WHEEL_PYTHON}')
    if changed:
        log(f'[fix_ros_wheel_paths] {changed} CMake files now point at {reps[0][1]} and '
            f'{reps[1][1]}')
    return changed, missing


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    prefix = pathlib.Path(argv[0] if argv else sys.prefix).resolve()
    _, missing = fix(prefix)
    if missing:
        print('[fix_ros_wheel_paths] FAILED: paths that do not exist here:\n  '
              + '\n  '.join(sorted(missing)), file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
