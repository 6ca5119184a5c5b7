"""The rig's pose in ROS: pose files, /tf_static, the baseline check and markers, with real rclpy.

fuzzy_best_point_node must place matches made by a rig that its rig.* defaults do not describe
when given that rig's pose file or its /tf_static; it must refuse a configured baseline that the
calibration contradicts, and use the colour images that come with the matches;
rig_transforms_node must publish a pose file as standard TF that a late subscriber still
receives. Each test has a ROS domain of its own and waits on messages.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from ros_waiting import wait_until

pytestmark = pytest.mark.ros

TIMEOUT = 30.0  # [s] generous: DDS discovery alone can take about 2 s
# A rig the node's rig.* defaults (alpha 45, theta 0, midpoint (0.2, -0.25, 0.4)) do not
# describe: turned, less tilted, further back.
OTHER_RIG = dict(alpha_deg=35.0, theta_deg=12.0, x0_m=0.24, y0_m=-0.28, z0_m=0.42,
                 vergence_deg=4.0, baseline_m=0.07)


def other_rig():
    from stereo_fuzzy_perception.core.rig_geometry import StereoRig

    return StereoRig(**OTHER_RIG)


def make_scene(rig, seed: int = 3, kind: str = 'cubic_square'):
    from stereo_fuzzy_perception.simulation.synthetic_scenes import GeometricSceneSource

    return GeometricSceneSource(rig=rig).scene(np.random.default_rng(seed), kind)


def matches_message(scene, stamp_sec: int):
    from std_msgs.msg import Header
    from stereo_fuzzy_perception.nodes.conversions import (
        calibration_to_camera_info,
        matched_points_to_cloud,
    )

    from stereo_fuzzy_msgs.msg import StereoMatches

    header = Header(frame_id='left_camera_optical_frame')
    header.stamp.sec = stamp_sec
    msg = StereoMatches(header=header, method='zncc', window_size=9)
    msg.left_info = calibration_to_camera_info(scene.left, header)
    msg.right_info = calibration_to_camera_info(scene.right, header)
    msg.points = matched_points_to_cloud(scene.points, header)
    return msg


class Harness:
    """fuzzy_best_point_node plus a probe that publishes matches and /tf_static."""

    def __init__(self, context, overrides=None):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.parameter import Parameter
        from stereo_fuzzy_perception.nodes import qos
        from stereo_fuzzy_perception.nodes.fuzzy_best_point_node import FuzzyBestPointNode
        from visualization_msgs.msg import MarkerArray

        from stereo_fuzzy_msgs.msg import FuzzyDecision, StereoMatches

        parameters = [Parameter(name, value=value) for name, value in (overrides or {}).items()]
        self.node = FuzzyBestPointNode(context=context, parameter_overrides=parameters)
        self.probe = rclpy.create_node('probe', context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.probe)
        self.decisions: list = []
        self.markers: list = []
        self.diagnostics: list = []
        self.probe.create_subscription(FuzzyDecision, 'best_point/decision',
                                       self.decisions.append, qos.RESULTS)
        self.probe.create_subscription(MarkerArray, 'best_point/markers', self.markers.append,
                                       qos.RESULTS)
        from diagnostic_msgs.msg import DiagnosticArray

        self.probe.create_subscription(DiagnosticArray, '/diagnostics', self.diagnostics.append,
                                       qos.DIAGNOSTICS)
        self.publisher = self.probe.create_publisher(StereoMatches, 'matches',
                                                     qos.RESULTS)
        wait_until(lambda: self.publisher.get_subscription_count() > 0
                   and self.node.decision_publisher.get_subscription_count() > 0
                   and self.node.markers_publisher.get_subscription_count() > 0,
                   TIMEOUT, 'the node and the probe to discover each other', self.executor)

    def send(self, msg, decisions_expected: int):
        self.publisher.publish(msg)
        wait_until(lambda: len(self.decisions) >= decisions_expected, TIMEOUT,
                   f'{decisions_expected} decision(s)', self.executor)
        return self.decisions[decisions_expected - 1]

    def close(self):
        self.executor.shutdown()
        self.node.destroy_node()
        self.probe.destroy_node()


@pytest.fixture
def harness(ros_context):
    created = []

    def make(overrides=None):
        created.append(Harness(ros_context, overrides))
        return created[-1]

    yield make
    for item in created:
        item.close()


def best_point_error_mm(decision, scene) -> float:
    p = decision.best_point_world
    return 1000.0 * float(np.linalg.norm(np.array([p.x, p.y, p.z]) - scene.target_world))


def test_pose_file_places_a_rig_the_rig_numbers_do_not_describe(harness, tmp_path):
    from stereo_fuzzy_perception.core.pose_file import write_pose_file
    from stereo_fuzzy_perception.core.rig_pose import chapter_left_camera_transform

    rig = other_rig()
    scene = make_scene(rig)
    pose_file = tmp_path / 'rig_pose.yaml'
    write_pose_file(pose_file, [chapter_left_camera_transform(rig)])
    with_file = harness({'rig_pose_file': str(pose_file)})
    decision = with_file.send(matches_message(scene, stamp_sec=1), 1)
    assert decision.status == 'ok', decision.status
    assert best_point_error_mm(decision, scene) < 3.0
    # The same matches placed with the default rig numbers land elsewhere or nowhere.
    without = harness()
    wrong = without.send(matches_message(scene, stamp_sec=2), 1)
    assert not wrong.has_best_point or best_point_error_mm(wrong, scene) > 20.0


def test_bad_pose_file_ends_the_start_naming_the_file(harness, tmp_path):
    pose_file = tmp_path / 'rig_pose.yaml'
    pose_file.write_text('left_camera_pose: {frame_id: world}\n')
    from stereo_fuzzy_parameters.declaration import StartupError

    with pytest.raises(StartupError, match='rig_pose.yaml: section .left_camera_pose. has no '
                                         'ros__parameters'):
        harness({'rig_pose_file': str(pose_file)})


def test_baseline_contradicted_by_the_first_matches_refuses_every_decision(harness):
    """Without calibration files: one ERROR naming both baselines, /diagnostics ERROR, and every
    later decision refused with that reason, even one whose calibration would agree."""
    from diagnostic_msgs.msg import DiagnosticStatus
    from rcl_interfaces.msg import Log
    from rclpy.qos import QoSProfile
    from stereo_fuzzy_perception.core.rig_geometry import StereoRig

    scene = make_scene(StereoRig())  # calibrated with a 0.06 m baseline
    run = harness({'rig.baseline_m': 0.10})
    logs: list = []
    run.probe.create_subscription(Log, '/rosout', logs.append, QoSProfile(depth=100))
    refused = run.send(matches_message(scene, stamp_sec=1), 1)
    assert not refused.has_best_point
    assert refused.status.startswith('rig_mismatch: rig.baseline_m=0.1000 m disagrees'), (
        refused.status)
    assert '0.0600 m' in refused.status
    # A 0.10 m calibration agrees with rig.baseline_m, but the node already knows the rig
    # contradicts its configuration: still refused, with the first reason.
    agreeing_scene = make_scene(StereoRig(baseline_m=0.10))
    later = run.send(matches_message(agreeing_scene, stamp_sec=2), 2)
    assert later.status == refused.status
    assert run.node.decisions['rig_mismatch'] == 2 and run.node.decisions['ok'] == 0
    wait_until(lambda: any(status.level == DiagnosticStatus.ERROR for array in run.diagnostics
                           for status in array.status), TIMEOUT, '/diagnostics at ERROR',
               run.executor)
    error = next(status for array in run.diagnostics for status in array.status
                 if status.level == DiagnosticStatus.ERROR)
    assert error.message.startswith('rig_mismatch: rig.baseline_m=0.1000 m')
    assert '0.0600 m' in error.message
    wait_until(lambda: any(log.name == 'fuzzy_best_point_node' and log.level == Log.ERROR
                           for log in logs), TIMEOUT, 'the ERROR on /rosout', run.executor)
    errors = [log.msg for log in logs if log.level == Log.ERROR]
    assert len(errors) == 1, errors
    assert '0.1000 m' in errors[0] and '0.0600 m' in errors[0] and 'allowed' in errors[0]
    agreeing = harness({'rig.baseline_m': 0.06})
    assert agreeing.send(matches_message(scene, stamp_sec=3), 1).status == 'ok'


def test_baseline_contradicted_by_the_calibration_files_ends_the_start(harness, tmp_path):
    from stereo_fuzzy_parameters.declaration import StartupError
    from stereo_fuzzy_perception.core.camera_calibration_file import write_calibration_yaml
    from stereo_fuzzy_perception.core.rig_geometry import StereoRig

    scene = make_scene(StereoRig())  # calibrated with a 0.06 m baseline
    write_calibration_yaml(scene.left, 'left', tmp_path / 'left.yaml')
    write_calibration_yaml(scene.right, 'right', tmp_path / 'right.yaml')
    files = {'left_calibration_file': str(tmp_path / 'left.yaml'),
             'right_calibration_file': str(tmp_path / 'right.yaml')}
    with pytest.raises(StartupError, match=r'rig.baseline_m=0.1000 m disagrees with the '
                                           r"calibration's baseline 0.0600 m.*allowed: 0, or "
                                           r'within') as refused:
        harness({'rig.baseline_m': 0.10, **files})
    assert 'right.yaml' in str(refused.value)
    with pytest.raises(StartupError, match='left_calibration_file and right_calibration_file '
                                           'go together'):
        harness({'rig.baseline_m': 0.06, 'left_calibration_file': files['left_calibration_file']})
    agreeing = harness({'rig.baseline_m': 0.06, **files})
    assert agreeing.send(matches_message(scene, stamp_sec=1), 1).status == 'ok'


def test_tf_static_places_the_camera_when_no_pose_file_is_given(harness):
    from stereo_fuzzy_perception.core.rig_pose import chapter_left_camera_transform
    from stereo_fuzzy_perception.nodes import qos
    from stereo_fuzzy_perception.nodes.conversions import transforms_to_tf_message

    from tf2_msgs.msg import TFMessage

    rig = other_rig()
    scene = make_scene(rig)
    run = harness()
    tf_static = run.probe.create_publisher(TFMessage, '/tf_static', qos.TF_STATIC_BROADCAST)
    tf_static.publish(transforms_to_tf_message([chapter_left_camera_transform(rig)],
                                               run.probe.get_clock().now().to_msg()))
    wait_until(lambda: run.node._static_transforms, TIMEOUT, 'the node to receive /tf_static',
               run.executor)
    decision = run.send(matches_message(scene, stamp_sec=1), 1)
    assert decision.status == 'ok', decision.status
    assert best_point_error_mm(decision, scene) < 3.0

    def reported_source() -> str:
        if not run.diagnostics:
            return ''
        values = {kv.key: kv.value for kv in run.diagnostics[-1].status[0].values}
        return values.get('camera pose from', '')

    wait_until(lambda: reported_source() == '/tf_static', TIMEOUT,
               "/diagnostics naming /tf_static as the camera pose's source", run.executor)


def test_markers_show_area_border_numbered_centres_and_best_point(harness):
    from stereo_fuzzy_perception.core.rig_geometry import StereoRig
    from visualization_msgs.msg import Marker

    scene = make_scene(StereoRig())
    run = harness()
    decision = run.send(matches_message(scene, stamp_sec=1), 1)
    wait_until(lambda: run.markers, TIMEOUT, 'the markers', run.executor)
    markers = run.markers[-1].markers
    assert markers[0].action == Marker.DELETEALL
    by_id = {marker.id: marker for marker in markers[1:]}
    assert all(marker.header.frame_id == 'world' for marker in markers)
    assert by_id[0].type == Marker.POINTS and len(by_id[0].points) == decision.points_used
    assert by_id[1].type == Marker.SPHERE_LIST and len(by_id[1].points) == 4
    assert [by_id[6 + k].text for k in range(4)] == ['1', '2', '3', '4']
    for k in range(4):
        centre = decision.area_centres[k]
        position = by_id[2 + k].pose.position
        assert (position.x, position.y, position.z) == pytest.approx(
            (centre.x, centre.y, centre.z))
    best = by_id[10].pose.position
    p = decision.best_point_world
    assert (best.x, best.y, best.z) == pytest.approx((p.x, p.y, p.z))


def test_rig_transforms_node_publishes_the_pose_file_and_right_camera_on_tf_static(
        ros_context, tmp_path):
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from stereo_fuzzy_perception.core.camera_calibration_file import write_calibration_yaml
    from stereo_fuzzy_perception.core.frame_transforms import lookup_transform
    from stereo_fuzzy_perception.core.pose_file import write_pose_file
    from stereo_fuzzy_perception.core.rig_pose import chapter_left_camera_transform
    from stereo_fuzzy_perception.nodes import qos
    from stereo_fuzzy_perception.nodes.conversions import tf_message_to_transforms
    from stereo_fuzzy_perception.nodes.rig_transforms_node import RigTransformsNode
    from stereo_fuzzy_perception.simulation.scene_model import SimulatedCamera
    from stereo_fuzzy_perception.simulation.scene_renderer import stereo_calibration

    from tf2_msgs.msg import TFMessage

    rig = other_rig()
    pose_file = tmp_path / 'rig_pose.yaml'
    write_pose_file(pose_file, [chapter_left_camera_transform(rig)])
    calibration = stereo_calibration(SimulatedCamera(), rig)
    write_calibration_yaml(calibration.left, 'left', tmp_path / 'left.yaml')
    write_calibration_yaml(calibration.right, 'right', tmp_path / 'right.yaml')
    node = RigTransformsNode(context=ros_context, parameter_overrides=[
        Parameter('rig_pose_file', value=str(pose_file)),
        Parameter('left_calibration_file', value=str(tmp_path / 'left.yaml')),
        Parameter('right_calibration_file', value=str(tmp_path / 'right.yaml'))])
    # A subscriber that comes later still gets them (transient local).
    listener = rclpy.create_node('listener', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    executor.add_node(listener)
    received: list = []
    listener.create_subscription(TFMessage, '/tf_static', received.append, qos.TF_STATIC)
    try:
        wait_until(lambda: received, TIMEOUT, 'the static transforms', executor)
        transforms = tf_message_to_transforms(received[0])
        assert [(t.frame_id, t.child_frame_id) for t in transforms] == [
            ('world', 'left_camera_optical_frame'),
            ('left_camera_optical_frame', 'right_camera_optical_frame')]
        np.testing.assert_allclose(
            lookup_transform(transforms, 'world', 'right_camera_optical_frame'),
            rig.world_from_right_camera(), atol=1e-6)
    finally:
        executor.shutdown()
        node.destroy_node()
        listener.destroy_node()


def test_rig_transforms_node_without_a_pose_file_ends_with_the_reason(ros_context):
    from stereo_fuzzy_parameters.declaration import StartupError
    from stereo_fuzzy_perception.nodes.rig_transforms_node import RigTransformsNode

    with pytest.raises(StartupError, match='rig_pose_file is empty'):
        RigTransformsNode(context=ros_context)


def test_driver_publishes_world_to_tool_on_tf_at_the_reported_position(ros_context, tmp_path):
    from gantry_harness import GantryClient, at, start_simulator
    from stereo_fuzzy_perception.nodes import qos

    from tf2_msgs.msg import TFMessage

    simulator = start_simulator(tmp_path)
    client = GantryClient(ros_context, tmp_path, {})
    transforms: list = []
    client.node.create_subscription(TFMessage, '/tf', transforms.append, qos.TF)
    try:
        client.wait_ready()
        client.publish_target(0.1, 0.2, 0.05)
        client.wait_state(lambda s: s.state == 'Idle' and at(s.world_position, 0.1, 0.2, 0.05),
                          'Idle at (0.1, 0.2, 0.05)')

        def tool_at_target() -> bool:
            if not transforms:
                return False
            (tool,) = transforms[-1].transforms
            t = tool.transform.translation
            return at(t, 0.1, 0.2, 0.05)

        client.wait(tool_at_target, '/tf with world -> tool at the target')
        (tool,) = transforms[-1].transforms
        assert (tool.header.frame_id, tool.child_frame_id) == ('world', 'tool')
        assert tool.transform.rotation.w == 1.0
    finally:
        client.close()
        simulator.stop()


def test_rendered_bags_carry_the_rig_they_were_rendered_with_on_tf_static(tmp_path):
    from rclpy.serialization import deserialize_message
    from stereo_fuzzy_perception.bag.bag_io import read_info, read_messages
    from stereo_fuzzy_perception.core.frame_transforms import lookup_transform
    from stereo_fuzzy_perception.nodes.conversions import tf_message_to_transforms
    from stereo_fuzzy_perception.simulation.scene_bag_writer import (
        SceneBagSettings,
        write_scene_bag,
    )
    from stereo_fuzzy_perception.simulation.scene_model import SimulatedCamera

    from tf2_msgs.msg import TFMessage

    rig = other_rig()
    path = tmp_path / 'bag'
    write_scene_bag(SceneBagSettings(path, object_types=('circle',), scenes_per_type=1,
                                     camera=SimulatedCamera(width=160, height=120), rig=rig))
    (message,) = list(read_messages(path, ['/tf_static']))
    transforms = tf_message_to_transforms(deserialize_message(message.data, TFMessage))
    np.testing.assert_allclose(
        lookup_transform(transforms, 'world', 'left_camera_optical_frame'),
        rig.world_from_left_camera(), atol=1e-9)
    np.testing.assert_allclose(
        lookup_transform(transforms, 'world', 'right_camera_optical_frame'),
        rig.world_from_right_camera(), atol=1e-6)
    from rosbags.interfaces import QosDurability

    (offered,) = read_info(path).topic('/tf_static').offered_qos
    assert offered.durability == QosDurability.TRANSIENT_LOCAL


def test_tf_message_stand_in_has_the_type_hash_of_jazzy_tf2_msgs():
    """Same type hash as Jazzy's own tf2_msgs/msg/TFMessage (which rosbags ships), so DDS,
    RViz, Foxglove and ros2 bag on a full install take our /tf and /tf_static as theirs."""
    import json
    from pathlib import Path

    from ament_index_python.packages import get_package_share_directory
    from rosbags.typesys import Stores, get_typestore

    description = Path(get_package_share_directory('tf2_msgs')) / 'msg' / 'TFMessage.json'
    hashes = {entry['type_name']: entry['hash_string']
              for entry in json.loads(description.read_text())['type_hashes']}
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    assert hashes['tf2_msgs/msg/TFMessage'] == jazzy.hash_rihs01('tf2_msgs/msg/TFMessage')


def test_a_new_rig_from_its_calibration_files_and_one_run_of_the_helper(harness, tmp_path):
    """The issue's goal: calibration YAMLs + one `rig_calibration board` run are all the
    geometry fuzzy_best_point_node needs for a rig its rig.* defaults do not describe."""
    import cv2
    from stereo_fuzzy_perception.core.board_pose import CheckerBoard
    from stereo_fuzzy_perception.core.camera_calibration_file import write_calibration_yaml
    from stereo_fuzzy_perception.rig.rig_calibration import main
    from stereo_fuzzy_perception.simulation.scene_renderer import SceneRenderer

    rig = other_rig()
    # An 11x8 board of 30 mm squares where the left camera's axis meets the surface, turned 12
    # degrees; the user measured where its corner lies.
    board = CheckerBoard(11, 8, 0.03, origin_x_m=0.0141, origin_y_m=-0.1654, yaw_deg=12.0)
    with SceneRenderer(rig=rig) as renderer:
        s = board.square_m
        width, height = board.size_m
        image, _ = renderer.render_plane(board.texture(), board.world_from_board(),
                                         (-s, -s, width + s, height + s))
        calibration = renderer.calibration
    cv2.imwrite(str(tmp_path / 'board.png'), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    write_calibration_yaml(calibration.left, 'left', tmp_path / 'left.yaml')
    write_calibration_yaml(calibration.right, 'right', tmp_path / 'right.yaml')
    pose_file = tmp_path / 'rig_pose.yaml'
    assert main(['board', '--left-calibration', str(tmp_path / 'left.yaml'), '--image',
                 str(tmp_path / 'board.png'), '--columns', '11', '--rows', '8', '--square',
                 '0.03', '--origin-x', '0.0141', '--origin-y', '-0.1654', '--yaw', '12',
                 '--output', str(pose_file)]) == 0
    scene = make_scene(rig, seed=5, kind='cylinder')
    run = harness({'rig_pose_file': str(pose_file)})
    decision = run.send(matches_message(scene, stamp_sec=1), 1)
    assert decision.status == 'ok', decision.status
    assert best_point_error_mm(decision, scene) < 3.0


def test_tf_message_stand_in_builds_nothing_where_the_real_tf2_msgs_is_installed(tmp_path):
    """On a full ROS install the stand-in must not shadow the real tf2_msgs (which tf2_ros needs
    for more than TFMessage): configured against an underlay that has the real package, it
    installs nothing."""
    import shutil
    import subprocess
    from pathlib import Path

    cmake = shutil.which('cmake')
    if cmake is None:
        pytest.skip('cmake is not installed')
    source = Path(__file__).resolve().parents[1] / 'src' / 'tf2_msgs'
    underlay = tmp_path / 'opt_ros_jazzy' / 'share' / 'tf2_msgs'
    (underlay / 'cmake').mkdir(parents=True)
    (underlay / 'msg').mkdir()
    (underlay / 'cmake' / 'tf2_msgsConfig.cmake').write_text('set(tf2_msgs_FOUND TRUE)\n')
    (underlay / 'msg' / 'TF2Error.msg').write_text('uint8 NO_ERROR = 0\n')
    build, install = tmp_path / 'build', tmp_path / 'install'
    configured = subprocess.run(
        [cmake, '-S', str(source), '-B', str(build),
         f'-DCMAKE_PREFIX_PATH={tmp_path / "opt_ros_jazzy"}', f'-DCMAKE_INSTALL_PREFIX={install}'],
        capture_output=True, text=True, timeout=120, check=False)
    assert configured.returncode == 0, configured.stderr
    assert 'this TFMessage-only stand-in builds nothing' in configured.stdout
    installed = subprocess.run([cmake, '--install', str(build)], capture_output=True, text=True,
                               timeout=60, check=False)
    assert installed.returncode == 0, installed.stderr
    assert not install.exists() or not any(install.rglob('*')), 'the stand-in installed files'


def test_installed_rig_transforms_node_serves_the_demo_pose_file_and_refuses_a_bad_one(
        ros_context, start_ros_process, tmp_path):
    from pathlib import Path

    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from stereo_fuzzy_perception.core.frame_transforms import lookup_transform
    from stereo_fuzzy_perception.core.rig_geometry import StereoRig
    from stereo_fuzzy_perception.nodes import qos
    from stereo_fuzzy_perception.nodes.conversions import tf_message_to_transforms

    from tf2_msgs.msg import TFMessage

    pose_file = (Path(__file__).resolve().parents[1] / 'src' / 'stereo_fuzzy_perception'
                 / 'config' / 'demo_rig_pose.yaml')
    process = start_ros_process('stereo_fuzzy_perception', 'rig_transforms_node', '--ros-args',
                                '-p', f'rig_pose_file:={pose_file}')
    listener = rclpy.create_node('listener', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(listener)
    received: list = []
    listener.create_subscription(TFMessage, '/tf_static', received.append, qos.TF_STATIC)
    try:
        wait_until(lambda: received, TIMEOUT, f'/tf_static:\n{process.output()}', executor)
        np.testing.assert_allclose(
            lookup_transform(tf_message_to_transforms(received[0]), 'world',
                             'left_camera_optical_frame'),
            StereoRig().world_from_left_camera(), atol=1e-9)
    finally:
        listener.destroy_node()
        executor.shutdown()
    assert process.interrupt() == 0, process.output()
    broken = tmp_path / 'broken.yaml'
    broken.write_text('left_camera_pose: [1, 2]\n')
    refused = start_ros_process('stereo_fuzzy_perception', 'rig_transforms_node', '--ros-args',
                                '-p', f'rig_pose_file:={broken}')
    wait_until(lambda: refused.process.poll() is not None, TIMEOUT, 'the refusal')
    assert refused.process.returncode == 1
    assert 'cannot start: ' in refused.output() and 'broken.yaml' in refused.output()
    assert 'Traceback' not in refused.output()


def test_colour_matches_let_the_node_find_a_disc_its_grey_looks_refuse(harness, tmp_path):
    """A far rig's 5 mm disc rendered by colour cameras (training scene 20, as in the package's
    test_colour_silhouette.py): the node given its matches with the colour images finds its
    top; given the same matches without them, it refuses the pair."""
    from std_msgs.msg import Header
    from stereo_fuzzy_perception.core.camera_model import StereoCalibration
    from stereo_fuzzy_perception.core.pose_file import write_pose_file
    from stereo_fuzzy_perception.core.rig_pose import chapter_left_camera_transform
    from stereo_fuzzy_perception.nodes.conversions import stereo_matches_message
    from stereo_fuzzy_perception.simulation.distribution_source import match_scene
    from stereo_fuzzy_perception.simulation.scene_distribution import split_plan

    matched = match_scene(split_plan('train', 50)[20].draw(), (1,), encoding='rgb8')
    scene = matched.matched[1]
    pose_file = tmp_path / 'rig_pose.yaml'
    write_pose_file(pose_file, [chapter_left_camera_transform(scene.rig)])
    run = harness({'rig_pose_file': str(pose_file), 'rig.baseline_m': scene.rig.baseline_m})
    header = Header(frame_id='left_camera_optical_frame')
    calibration = StereoCalibration(scene.left, scene.right)
    header.stamp.sec = 1
    grey_points = replace(scene.points, left_colour=None, right_colour=None)
    grey = run.send(stereo_matches_message(header, calibration, grey_points, matched.matcher,
                                           1), 1)
    assert not grey.has_best_point, grey.status
    header.stamp.sec = 2
    colour = run.send(stereo_matches_message(header, calibration, scene.points,
                                             matched.matcher, 1), 2)
    assert colour.status == 'ok', colour.status
    assert best_point_error_mm(colour, scene) <= 3.0

    def counted():
        if not run.diagnostics:
            return False
        values = {kv.key: kv.value for kv in run.diagnostics[-1].status[0].values}
        return (values.get('matches with colour images'),
                values.get('points from the colour silhouette')) == ('1', '1')

    wait_until(counted, TIMEOUT, 'diagnostics counting the colour point', run.executor)
