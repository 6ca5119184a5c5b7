"""The perception package's subsystems stay apart: the runtime never loads the simulator.

`core/` is the ROS-free runtime, `nodes/` the ROS adapters around it, `simulation/` the scene
simulator and selector training, `bag/` the MCAP bag tool. A node process must not pay for
pybullet or the renderer, nor break when they are missing, so each node module is imported in a
fresh interpreter and the modules it loaded are inspected.
"""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
PACKAGE = REPO_ROOT / 'src' / 'stereo_fuzzy_perception' / 'stereo_fuzzy_perception'
NODE_MODULES = [
    'stereo_fuzzy_perception.nodes.stereo_sync_node',
    'stereo_fuzzy_perception.nodes.correlation_node',
    'stereo_fuzzy_perception.nodes.fuzzy_best_point_node',
    'stereo_fuzzy_perception.nodes.rig_transforms_node',
    'stereo_fuzzy_perception.nodes.stereo_camera_node',
]
FORBIDDEN_IN_RUNTIME = ('pybullet', 'stereo_fuzzy_perception.simulation',
                        'stereo_fuzzy_perception.bag')


def _imported_modules(path: Path) -> set[str]:
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
        elif isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
    return names


@pytest.mark.parametrize('subsystem', ['core', 'nodes'])
def test_runtime_sources_import_nothing_from_simulation_or_bag_tool(subsystem):
    offenders = [
        f'{path.relative_to(PACKAGE)} imports {name}'
        for path in sorted((PACKAGE / subsystem).rglob('*.py'))
        for name in sorted(_imported_modules(path))
        if name.startswith(FORBIDDEN_IN_RUNTIME)
    ]
    assert not offenders, 'the runtime must not depend on the simulator or the bag tool:\n' + (
        '\n'.join(offenders))


def test_core_imports_no_ros():
    offenders = [
        f'{path.relative_to(PACKAGE)} imports {name}'
        for path in sorted((PACKAGE / 'core').rglob('*.py'))
        for name in sorted(_imported_modules(path))
        if name.split('.')[0] in {'rclpy', 'stereo_fuzzy_msgs', 'sensor_msgs', 'std_msgs',
                                  'geometry_msgs', 'stereo_msgs', 'rcl_interfaces'}
    ]
    assert not offenders, 'core/ is ROS-free (STYLE.md):\n' + '\n'.join(offenders)


@pytest.mark.ros
@pytest.mark.parametrize('module', NODE_MODULES)
def test_node_process_loads_no_simulator_or_bag_tool(module):
    probe = (
        'import importlib, sys\n'
        f'importlib.import_module({module!r})\n'
        'print("\\n".join(sorted(sys.modules)))\n'
    )
    result = subprocess.run([sys.executable, '-c', probe], capture_output=True, text=True,
                            timeout=120, check=False)
    assert result.returncode == 0, result.stderr
    loaded = [name for name in result.stdout.split() if name.startswith(FORBIDDEN_IN_RUNTIME)]
    assert not loaded, f'importing {module} loaded {loaded}'
    assert 'stereo_fuzzy_perception.nodes' in result.stdout.split(), (
        'the probe did not import the node package at all')
