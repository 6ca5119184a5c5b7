"""The README's real-hardware recipe works as written, with fake_gantry as the controller.

The fenced block after the `real-hardware recipe` marker in README.md runs in bash from the
repository root, exactly as written except that /dev/ttyUSB0 becomes fake_gantry's
pseudo-terminal and my_rig.yaml becomes chain/demo_params.yaml. Then the chain started in the
background is stopped with Ctrl-C, as a user would.
"""

from __future__ import annotations

import os
import re
import subprocess

import pytest
from ros_fixtures import REPO_ROOT
from ros_waiting import wait_until

pytestmark = [pytest.mark.ros, pytest.mark.system]

MARKER = '<!-- real-hardware recipe:'


def readme_recipe() -> str:
    """Return the bash block that follows the recipe marker in README.md."""
    readme = (REPO_ROOT / 'README.md').read_text()
    assert MARKER in readme, 'README.md lost the real-hardware recipe marker'
    after = readme[readme.index(MARKER):]
    match = re.search(r'```bash\n(?P<body>.*?)```', after, re.DOTALL)
    assert match, 'no ```bash block after the real-hardware recipe marker'
    return match['body']


def test_recipe_homes_the_machine_and_moves_it():
    recipe = readme_recipe()
    assert 'gantry --wait 60 home' in recipe and '/dev/ttyUSB0' in recipe
    assert recipe.index('home') < recipe.index('gantry move'), 'home before the first move'


def test_recipe_runs_as_written_against_fake_gantry(start_ros_process, tmp_path):
    link = tmp_path / 'grbl'
    fake = start_ros_process('cartesian_3p_driver', 'fake_gantry', '--ros-args', '-p',
                             f'link_path:={link}', '-p', 'tcp_port:=0', '-p', 'time_scale:=20.0')
    wait_until(link.exists, 60.0, f'the fake controller link:\n{fake.output()}')
    script = readme_recipe().replace('/dev/ttyUSB0', str(link)).replace(
        'my_rig.yaml', 'chain/demo_params.yaml')
    # The user's Ctrl-C on the background chain, then its exit code.
    script = ('set -e\n' + script + '\nchain_pid=$!\ntrap "kill -INT $chain_pid" EXIT\n'
              'kill -INT $chain_pid\ntrap - EXIT\nwait $chain_pid\n')
    result = subprocess.run(['bash', '-c', script], cwd=REPO_ROOT, capture_output=True,
                            text=True, timeout=600,
                            env=dict(os.environ, PYTHONUNBUFFERED='1'))
    output = result.stdout + result.stderr
    assert result.returncode == 0, output
    assert 'home done' in output, output
    assert 'homing required:  no' in output and 'connected:        yes' in output, output
    assert 'move reached: tool at (0.2000, 0.1500, 0.0500) m' in output, output
    assert '[launch_chain] started gantry_driver_node' in output, output
    assert re.search(r'\[launch_chain\] stopped: .*gantry_driver_node \(0\)', output), output
    assert fake.process.poll() is None, fake.output()


def test_every_command_the_readmes_name_is_on_path_after_env_sh():
    commands = ('stereo_sync_node', 'correlation_node', 'fuzzy_best_point_node',
                'gantry_driver_node', 'fake_gantry', 'gantry', 'bag', 'render_scenes',
                'launch_chain')
    result = subprocess.run(
        ['bash', '-c', 'source scripts/env.sh && for c in "$@"; do command -v "$c" || '
                       'echo "missing $c"; done', 'bash', *commands],
        cwd=REPO_ROOT, capture_output=True, text=True, timeout=60,
        env={key: value for key, value in os.environ.items() if key != 'PATH'}
        | {'PATH': '/usr/bin:/bin'})
    assert result.returncode == 0, result.stderr
    assert 'missing' not in result.stdout, result.stdout
    assert len(result.stdout.split()) == len(commands)
