"""The `gantry` command against the real driver and fake_gantry: outcomes and exit codes.

0 done, 1 refused or failed, 2 bad arguments, 3 no driver answered or the command did not finish
in time. The README's recipe (tests/test_real_hardware_recipe.py) covers the happy path.
"""

from __future__ import annotations

import os
import subprocess

import pytest
from ros_fixtures import executable_path
from ros_waiting import wait_until

pytestmark = pytest.mark.ros

DRIVER = 'cartesian_3p_driver'


def gantry(*arguments: str, timeout: float = 120.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(executable_path(DRIVER, 'gantry')), *arguments],
                          capture_output=True, text=True, timeout=timeout,
                          env=dict(os.environ, PYTHONUNBUFFERED='1'))


def test_no_driver_is_reported_with_exit_code_3(ros_domain_id):
    for command in (['home'], ['move', '0.1', '0.1', '0.02'], ['state']):
        result = gantry('--wait', '0.5', *command)
        assert result.returncode == 3, result
        assert 'no gantry driver' in result.stderr and 'gantry_driver_node' in result.stderr


def test_bad_arguments_exit_with_code_2(ros_domain_id):
    assert gantry('fly').returncode == 2
    assert gantry('move', '0.1', '0.1').returncode == 2
    result = gantry('--timeout', '0', 'home')
    assert result.returncode == 2 and '--timeout' in result.stderr


def test_refused_move_home_timeout_and_stop(start_ros_process, tmp_path):
    link = tmp_path / 'grbl'
    fake = start_ros_process(DRIVER, 'fake_gantry', '--ros-args', '-p', f'link_path:={link}',
                             '-p', 'tcp_port:=0')
    wait_until(link.exists, 60.0, f'the fake controller link:\n{fake.output()}')
    driver = start_ros_process(DRIVER, 'gantry_driver_node', '--ros-args', '-p',
                               f'port:={link}')
    # The controller boots in Alarm: the driver refuses to move before homing.
    refused = gantry('--wait', '60', 'move', '0.1', '0.1', '0.02')
    assert refused.returncode == 1, (refused, driver.output())
    assert 'move failed: refused' in refused.stderr  # not ready yet, or in Alarm
    assert gantry('home').returncode == 0
    # At real speed a 30 cm move takes seconds: a short timeout gives up and cancels it.
    slow = gantry('--timeout', '0.3', 'move', '0.35', '0.25', '0.02')
    assert slow.returncode == 3, slow
    assert 'did not finish within 0.3 s; cancelled it' in slow.stderr
    stopped = gantry('stop')
    assert stopped.returncode == 0 and 'stop done' in stopped.stdout, stopped
    state = gantry('state')
    assert state.returncode == 0 and 'connected:        yes' in state.stdout, state
