"""Repoint the ROS wheels' exported CMake files at this venv's Python and NumPy headers.

The ``ros-jazzy-*`` wheels were built with ``/opt/python/cp311-cp311``; the
``share/*/cmake/*.cmake`` files of the venv name its include directories, and CMake stops
("Imported target ... includes non-existent path") when a package such as crane_interfaces
links against them. This rewrites those paths to the running interpreter's
(``sysconfig.get_paths()['include']``, ``numpy.get_include()``), only in files under the
venv's ``share/``. Idempotent: a second run finds nothing to change. Run it with the venv's
Python (the Makefile does, before every build of crane_interfaces).

Usage: .venv/bin/python devtools/patch_ros_cmake.py [--check]
"""
import argparse
import sys
import sysconfig
from pathlib import Path

#: The wheel builder's interpreter, as the wheels' CMake files name it.
BUILDER = '/opt/python/cp311-cp311'
OLD_INCLUDE = f'{BUILDER}/include/python3.11'
OLD_NUMPY = f'{BUILDER}/lib/python3.11/site-packages/numpy/_core/include'


def replacements():
    import numpy
    include, numpy_include = sysconfig.get_paths()['include'], numpy.get_include()
    for path in (include, numpy_include):
        if not (Path(path) / ('Python.h' if path == include else 'numpy')).exists():
            sys.exit(f'patch_ros_cmake: {path} lacks the headers CMake will need')
    return {OLD_INCLUDE: include, OLD_NUMPY: numpy_include}


def patch(prefix: Path, check: bool = False) -> list[Path]:
    """The CMake files under ``prefix/share`` that name the builder's paths; rewritten unless ``check``."""
    subs = replacements()
    changed = []
    for path in sorted((prefix / 'share').glob('*/cmake/*.cmake')):
        text = path.read_text()
        if BUILDER not in text:
            continue
        new = text
        for old, repl in subs.items():
            new = new.replace(old, repl)
        if new != text:
            changed.append(path)
            if not check:
                path.write_text(new)
    return changed


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--check', action='store_true', help='only list the files that need the patch (exit 1 if any)')
    args = parser.parse_args(argv)
    if sys.prefix == sys.base_prefix:
        sys.exit('patch_ros_cmake: run it with the venv\'s Python, it only patches inside a venv')
    changed = patch(Path(sys.prefix), check=args.check)
    print(f'patch_ros_cmake: {len(changed)} CMake file(s) {"to patch" if args.check else "patched"} in {sys.prefix}')
    return 1 if args.check and changed else 0


if __name__ == '__main__':
    sys.exit(main())
