"""Every module a package imports at run time is declared: in its package.xml for rosdep on a
full ROS 2 install, and in requirements.in for this repository's own venv.

Imports are read from the sources (AST), so a new import without a declaration fails here
instead of on a user's machine with an ImportError.
"""

from __future__ import annotations

import ast
import sys
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ('stereo_fuzzy_perception', 'cartesian_3p_driver', 'stereo_fuzzy_parameters')
# Python module -> (rosdep key, PyPI distribution). A key of None has no rosdep rule: the
# package.xml must name the distribution in a comment (README: "Dependencies of a full ROS 2
# install").
THIRD_PARTY = {
    'numpy': ('python3-numpy', 'numpy'),
    'cv2': ('python3-opencv', 'opencv-python-headless'),
    'yaml': ('python3-yaml', 'pyyaml'),
    'scipy': ('python3-scipy', 'scipy'),
    'numba': ('python3-numba', 'numba'),
    'llvmlite': ('python3-numba', 'numba'),  # numba's compiler, installed with it
    'pybullet': ('python3-pybullet-pip', 'pybullet'),
    'serial': ('python3-serial', 'pyserial'),
    'rosbags': (None, 'rosbags'),
    'mcap': (None, 'mcap'),
    'backports': (None, 'rosbags'),  # backports.zstd, a dependency of rosbags
    'compression': (None, 'rosbags'),  # the standard library's zstd from Python 3.14 on
}
# ROS packages imported under their own name (exec_depend on the package).
ROS_MODULES = {'rclpy', 'std_msgs', 'std_srvs', 'sensor_msgs', 'stereo_msgs', 'geometry_msgs',
               'diagnostic_msgs', 'visualization_msgs', 'rosgraph_msgs', 'rcl_interfaces',
               'action_msgs', 'builtin_interfaces', 'stereo_fuzzy_msgs',
               'stereo_fuzzy_parameters', 'launch', 'launch_ros', 'ament_index_python',
               'cartesian_3p_driver', 'tf2_msgs'}
RUNTIME_ONLY_IN = {'launch': 'launch_ros', 'ament_index_python': 'launch_ros'}


def imported_modules(package: str) -> dict[str, set[str]]:
    """Return {top-level module: files importing it} for the package's run-time sources."""
    root = REPO_ROOT / 'src' / package
    found: dict[str, set[str]] = {}
    sources = [p for p in (root / package).rglob('*.py')] + list((root / 'launch').glob('*.py'))
    for path in sources:
        for node in ast.walk(ast.parse(path.read_text())):
            names = []
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names = [node.module]
            elif isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            for name in names:
                found.setdefault(name.split('.')[0], set()).add(str(path.relative_to(root)))
    return found


def declared(package: str) -> tuple[set[str], str]:
    """Return the package.xml's exec/run dependencies and its whole text (for comments)."""
    path = REPO_ROOT / 'src' / package / 'package.xml'
    tree = ElementTree.parse(path)
    keys = {element.text.strip() for tag in ('exec_depend', 'depend')
            for element in tree.getroot().iter(tag) if element.text}
    return keys, path.read_text()


def requirements() -> set[str]:
    names = set()
    for line in (REPO_ROOT / 'requirements.in').read_text().splitlines():
        line = line.split('#')[0].strip()
        if line:
            names.add(line.split('[')[0].lower())
    return names


@pytest.mark.parametrize('package', PACKAGES)
def test_every_run_time_import_is_declared(package):
    modules = imported_modules(package)
    keys, text = declared(package)
    local = {package, *(p.stem for p in (REPO_ROOT / 'src' / package / package).iterdir())}
    missing = []
    for module, files in sorted(modules.items()):
        if module in sys.stdlib_module_names or module in local or module == '__future__':
            continue
        if module in ROS_MODULES:
            if module != package and module not in keys and RUNTIME_ONLY_IN.get(
                    module) not in keys:
                missing.append(f'{module} (imported by {sorted(files)[0]}): <exec_depend>')
            continue
        assert module in THIRD_PARTY, (
            f'{package} imports {module} ({sorted(files)}): add it to THIRD_PARTY here, to '
            'package.xml and to requirements.in')
        key, distribution = THIRD_PARTY[module]
        if key is not None and key not in keys:
            missing.append(f'{module}: <exec_depend>{key}</exec_depend>')
        if key is None and distribution not in text:
            missing.append(f'{module}: a comment naming the PyPI distribution {distribution}')
        if distribution not in requirements():
            missing.append(f'{module}: {distribution} in requirements.in')
    assert not missing, f'{package}/package.xml or requirements.in lacks:\n' + '\n'.join(missing)
