"""A value a node cannot start with ends it with ONE line naming the parameter, the value and
what is allowed, and a non-zero exit code; no traceback. The executables start as `ros2 run`
would start them, with the bad value on the command line."""

import pytest
from ros_waiting import wait_until

pytestmark = pytest.mark.ros

TIMEOUT = 120.0  # [s] generous: the first start of a node imports numpy, OpenCV and numba

PACKAGE_OF = {'stereo_sync_node': 'stereo_fuzzy_perception',
              'correlation_node': 'stereo_fuzzy_perception',
              'fuzzy_best_point_node': 'stereo_fuzzy_perception',
              'stereo_camera_node': 'stereo_fuzzy_perception',
              'gantry_driver_node': 'cartesian_3p_driver', 'fake_gantry': 'cartesian_3p_driver'}

# (executable, --ros-args parameters, words the one line must hold: name, value, allowed)
BAD_STARTS = [
    ('correlation_node', ['window_size:=10'], ['window_size', '10', 'odd']),
    ('correlation_node', ['window_size:=40'], ['window_size', '40', 'allowed [3, 31]']),
    ('correlation_node', ['window_size:=abc'], ['window_size', "'abc'", 'an integer']),
    ('correlation_node', ['method:=foo'], ['method', "'foo'", 'zncc, plain']),
    ('fuzzy_best_point_node', ['rule_base_file:=/nope.yaml'],
     ['rule_base_file', "'/nope.yaml'", 'rule base']),
    ('fuzzy_best_point_node', ['workspace_max_m:=[0.4,0.3]'],
     ['workspace_max_m', '[0.4, 0.3]', 'allowed: 3 values']),
    ('fuzzy_best_point_node', ['workspace_max_m:=[0.4,0.3,-0.1]'],
     ['workspace_max_m', '-0.1', 'must exceed workspace_min_m']),
    ('stereo_sync_node', ['slop_s:=1'], ['slop_s', '1', 'floating-point number']),
    ('stereo_camera_node', ['frame_rate_hz:=15.0'],
     ['stereo_camera_node needs', 'left_device', 'right_calibration_file']),
    ('stereo_camera_node', ['left_device:=0', 'right_device:=1',
                            'left_calibration_file:=/nope.yaml',
                            'right_calibration_file:=/nope.yaml'],
     ['left_calibration_file', '/nope.yaml', 'calibration file']),
    ('gantry_driver_node', ['port:=/nonexistent', 'workspace_min_m:=[0.0,0.0,0.3]'],
     ['workspace_max_m', 'workspace_min_m=[0.0, 0.0, 0.3]', 'must exceed']),
    ('gantry_driver_node', ['port:=/nonexistent', 'new_target_policy:=drop'],
     ['new_target_policy', "'drop'", 'queue, replace']),
    ('fake_gantry', ['tcp_port:=0', 'max_travel_mm:=[400.0,300.0]'],
     ['max_travel_mm', '[400.0, 300.0]', 'allowed: 3 values']),
    ('fake_gantry', ['tcp_port:=0', 'soft_limits:=true', 'homing_enabled:=false'],
     ['soft_limits=true', 'homing_enabled=true']),
    ('fake_gantry', ['tcp_port:=0', 'link_path:=/nonexistent/dir/tty'],
     ['link_path', '/nonexistent/dir/tty', 'No such file']),
]


@pytest.mark.parametrize(('executable', 'parameters', 'words'), BAD_STARTS,
                         ids=[f'{entry[0]}-{entry[1][-1]}' for entry in BAD_STARTS])
def test_bad_start_up_value_ends_the_node_with_one_fatal_line(
        start_ros_process, executable, parameters, words):
    arguments = ['--ros-args']
    for parameter in parameters:
        arguments += ['-p', parameter]
    process = start_ros_process(PACKAGE_OF[executable], executable, *arguments)
    output = process.wait_for_exit(TIMEOUT)
    lines = [line for line in output.splitlines() if line.strip()]
    assert process.process.returncode != 0, f'{executable} exited 0 with {parameters}'
    assert 'Traceback' not in output, output
    assert len(lines) == 1, f'one line expected, {len(lines)} printed:\n{output}'
    assert '[FATAL]' in lines[0] and f'[{executable}]' in lines[0], lines[0]
    for word in words:
        assert word in lines[0], f'{word!r} missing from the start-up error: {lines[0]}'


def test_baseline_the_calibration_files_contradict_ends_the_node_with_both_numbers(
        start_ros_process, tmp_path):
    from stereo_fuzzy_perception.core.camera_calibration_file import write_calibration_yaml
    from stereo_fuzzy_perception.core.rig_geometry import StereoRig
    from stereo_fuzzy_perception.simulation.scene_model import SimulatedCamera
    from stereo_fuzzy_perception.simulation.scene_renderer import stereo_calibration

    calibration = stereo_calibration(SimulatedCamera(width=160, height=120),
                                     StereoRig(baseline_m=0.06))
    write_calibration_yaml(calibration.left, 'left', tmp_path / 'left.yaml')
    write_calibration_yaml(calibration.right, 'right', tmp_path / 'right.yaml')
    process = start_ros_process(
        'stereo_fuzzy_perception', 'fuzzy_best_point_node', '--ros-args',
        '-p', 'rig.baseline_m:=0.1', '-p', f'left_calibration_file:={tmp_path / "left.yaml"}',
        '-p', f'right_calibration_file:={tmp_path / "right.yaml"}')
    lines = [line for line in process.wait_for_exit(TIMEOUT).splitlines() if line.strip()]
    assert process.process.returncode != 0
    assert len(lines) == 1, lines
    for word in ('[FATAL]', 'rig.baseline_m=0.1000 m', 'baseline 0.0600 m', 'allowed'):
        assert word in lines[0], f'{word!r} missing from the start-up error: {lines[0]}'


def test_a_parameter_the_node_does_not_have_is_named_with_the_closest_one(start_ros_process):
    process = start_ros_process('stereo_fuzzy_perception', 'stereo_sync_node', '--ros-args',
                                '-p', 'slop:=0.02')
    wait_until(lambda: 'pairing' in process.output() or process.process.poll() is not None,
               TIMEOUT, 'stereo_sync_node to start')
    assert process.process.poll() is None, (
        f'an unknown name must not stop the node:\n{process.output()}')
    warnings = [line for line in process.output().splitlines() if '[WARN]' in line]
    assert len(warnings) == 1, process.output()
    assert 'slop is not a parameter of stereo_sync_node' in warnings[0], warnings[0]
    assert 'did you mean slop_s?' in warnings[0], warnings[0]
    assert process.interrupt() == 0, process.output()
