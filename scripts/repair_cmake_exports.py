"""Point the ROS message wheels' CMake exports at this machine's Python and numpy headers.

The wheels were built under /opt/python/cp3XY-cp3XY and their exported targets name that
Python's include directory and numpy's, which do not exist here; CMake's generate step then fails
with "includes non-existent path". Only files under <venv>/share/*/cmake are rewritten, so the
repair stays inside the virtual environment. Running it again changes nothing.
"""

import re
import sys
import sysconfig
from pathlib import Path

import numpy

BAKED_PREFIX = re.compile(r'/opt/python/cp3\d+-cp3\d+')


def repair(venv: Path) -> int:
    """Rewrite the baked include paths under `venv`/share/*/cmake; return the files changed."""
    python_include = sysconfig.get_paths()['include']
    numpy_include = numpy.get_include()
    baked_python = re.compile(BAKED_PREFIX.pattern + r'/include/python3\.\d+')
    baked_numpy = re.compile(
        BAKED_PREFIX.pattern + r'/lib/python3\.\d+/site-packages/numpy/(_core|core)/include')
    changed = 0
    for cmake_file in sorted(venv.glob('share/*/cmake/*.cmake')):
        text = cmake_file.read_text()
        if not BAKED_PREFIX.search(text):
            continue
        text = baked_numpy.sub(numpy_include, baked_python.sub(python_include, text))
        cmake_file.write_text(text)
        changed += 1
    return changed


if __name__ == '__main__':
    count = repair(Path(sys.argv[1]))
    print(f'[setup] repaired include paths in {count} CMake export files')
