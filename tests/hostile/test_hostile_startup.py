"""Hostile files given at start-up end the node with one FATAL line, never a hang or traceback.

Issue #15 item 7 at start: a FIFO as rule_base_file used to block the node before it ever
spun; /dev/zero and an .npy as network_file are refused by the same checks as at run time,
and so is a readable calibration file that cannot be used (an unknown distortion model); the
one line names the parameter and the reason.
"""

from __future__ import annotations

import os
from dataclasses import replace

import numpy as np
import pytest
from hostile_messages import right_camera

pytestmark = pytest.mark.ros

TIMEOUT = 120.0  # [s] generous: the first start of a node imports numpy, OpenCV and numba


def bad_starts(tmp_path):
    from stereo_fuzzy_perception.core.camera_calibration_file import write_calibration_yaml

    fifo = tmp_path / 'rules.fifo'
    os.mkfifo(fifo)
    npy = tmp_path / 'weights.npy'
    np.save(npy, np.zeros(3))
    calibration = right_camera()
    good = tmp_path / 'good.yaml'
    write_calibration_yaml(calibration, 'good', good)
    unknown_model = tmp_path / 'unknown_model.yaml'  # readable, but not usable
    write_calibration_yaml(replace(calibration, distortion_model='fisheye62'), 'bad',
                           unknown_model)
    return [
        ('fuzzy_best_point_node', [f'rule_base_file:={fifo}'], ['rule_base_file', 'a FIFO']),
        ('fuzzy_best_point_node', ['rule_base_file:=/dev/zero'],
         ['rule_base_file', 'a character device']),
        ('fuzzy_best_point_node', [f'network_file:={npy}'],
         ['network_file', 'not an .npz archive']),
        ('stereo_camera_node', ['left_device:=0', 'right_device:=1',
                                f'left_calibration_file:={good}',
                                f'right_calibration_file:={unknown_model}'],
         ['right_calibration_file', "distortion model 'fisheye62'"]),
    ]


@pytest.mark.parametrize('case', range(4))
def test_a_hostile_file_at_start_ends_the_node_with_one_line(start_ros_process, tmp_path,
                                                            case):
    executable, parameters, words = bad_starts(tmp_path)[case]
    arguments = ['--ros-args']
    for parameter in parameters:
        arguments += ['-p', parameter]
    process = start_ros_process('stereo_fuzzy_perception', executable, *arguments)
    output = process.wait_for_exit(TIMEOUT)
    assert process.process.returncode != 0, f'{executable} exited 0 with {parameters}'
    assert 'Traceback' not in output, output
    fatal = [line for line in output.splitlines() if 'FATAL' in line]
    assert len(fatal) == 1, output
    assert all(word in fatal[0] for word in words), (words, fatal[0])
