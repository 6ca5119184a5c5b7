"""render_scenes: render seeded stereo scenes straight into a rosbag2 (MCAP) bag.

The bag first carries the rig the scenes were rendered with, at the first scene's time:

  /tf_static                                tf2_msgs/TFMessage (transient local): world ->
                                            left_camera_optical_frame -> right_camera_optical_frame

so a replay places the cameras without rig parameters. Then each scene becomes one instant of
the bag, every message stamped alike:

  /left/camera_info, /right/camera_info     sensor_msgs/CameraInfo (K, D, R, P of the rig)
  /ground_truth/target                      geometry_msgs/PointStamped, frame `world`
  /ground_truth/object                      visualization_msgs/Marker, frame `world`
  /left/image_raw, /right/image_raw         sensor_msgs/Image

Scenes are `--period` seconds apart so the chain can finish one before the next. Scene k of a
bag is random_scene(seed * 10000 + k, types[k % len(types)]), so the same command always writes
the same messages, and any scene can be rendered again on its own.

Usage:
  render_scenes -o bags/demo_scenes --scenes-per-type 3 --seed 1 --encoding mono8
"""

from __future__ import annotations

import argparse
import copy
import shlex
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from builtin_interfaces.msg import Time
from rclpy.serialization import serialize_message
from rosbags.typesys.store import Typestore
from std_msgs.msg import Header

from stereo_fuzzy_perception.bag.bag_format import BagError, make_qos
from stereo_fuzzy_perception.bag.bag_reader import read_info
from stereo_fuzzy_perception.bag.bag_summary import format_info
from stereo_fuzzy_perception.bag.bag_writer import COMPRESSIONS, BagWriter
from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.rig_geometry import StereoRig
from stereo_fuzzy_perception.core.rig_pose import (
    chapter_left_camera_transform,
    right_camera_transform,
)
from stereo_fuzzy_perception.nodes.conversions import (
    array_to_image,
    calibration_to_camera_info,
    transforms_to_tf_message,
)
from stereo_fuzzy_perception.simulation.scene_distribution import draw_rig, draw_scene
from stereo_fuzzy_perception.simulation.scene_messages import (
    ground_truth_to_marker,
    ground_truth_to_target,
)
from stereo_fuzzy_perception.simulation.scene_model import (
    OBJECT_TYPES,
    ObjectType,
    SceneError,
    SimulatedCamera,
    random_scene,
)
from stereo_fuzzy_perception.simulation.scene_renderer import (
    RENDER_ENCODINGS,
    SceneRenderer,
    SensorModel,
    StereoFrame,
)

TOPICS = {
    '/left/camera_info': 'sensor_msgs/msg/CameraInfo',
    '/right/camera_info': 'sensor_msgs/msg/CameraInfo',
    '/ground_truth/target': 'geometry_msgs/msg/PointStamped',
    '/ground_truth/object': 'visualization_msgs/msg/Marker',
    '/left/image_raw': 'sensor_msgs/msg/Image',
    '/right/image_raw': 'sensor_msgs/msg/Image',
}
# The rig, once at the start of the bag, as tf2_ros' static broadcaster offers it.
RIG_TOPICS = {'/tf_static': 'tf2_msgs/msg/TFMessage'}
WORLD_FRAME = 'world'
SEED_STRIDE = 10000


@dataclass(frozen=True)
class SceneBagSettings:
    """What render_scenes writes (defaults: the demo bag's settings apart from the seed)."""

    output: Path
    object_types: tuple[ObjectType, ...] = OBJECT_TYPES
    scenes_per_type: int = 3
    seed: int = 0
    camera: SimulatedCamera = SimulatedCamera()
    rig: StereoRig = StereoRig()
    sensor: SensorModel = SensorModel()
    encoding: str = 'rgb8'
    compression: str = 'zstd'
    compression_level: int = 19
    period_s: float = 1.0
    start_time_s: float = 1_700_000_000.0
    distribution_rig: int | None = None

    def scene_plan(self) -> list[tuple[int, ObjectType]]:
        """Return (scene seed, object type) of every scene, in bag order."""
        count = self.scenes_per_type * len(self.object_types)
        return [(self.seed * SEED_STRIDE + k, self.object_types[k % len(self.object_types)])
                for k in range(count)]


def _stamp(time_ns: int) -> Time:
    return Time(sec=time_ns // 1_000_000_000, nanosec=time_ns % 1_000_000_000)


def canonical_cdr(data: bytes, msgtype: str, typestore: Typestore) -> bytes:
    """Return `data` re-serialized with zeroed alignment padding, padded to 4 bytes.

    rclpy's serializer leaves whatever was in memory in the padding bytes between fields, so two
    runs would write different bytes for the same messages; rosbags writes zeros. DDS delivers
    payloads zero-padded to a multiple of 4 bytes, so padding here too makes a played and
    re-recorded bag byte-identical to the original.
    """
    canonical = bytes(typestore.serialize_cdr(typestore.deserialize_cdr(data, msgtype), msgtype))
    return canonical + bytes(-len(canonical) % 4)


def frame_messages(frame: StereoFrame, stamp_ns: int) -> list[tuple[str, bytes]]:
    """Return (topic, CDR bytes) of one rendered scene, every header stamped `stamp_ns` [ns]."""
    stamp = _stamp(stamp_ns)
    calibration = frame.calibration

    def header(frame_id: str) -> Header:
        return Header(stamp=stamp, frame_id=frame_id)

    left_header = header(calibration.left.frame_id)
    right_header = header(calibration.right.frame_id)
    messages = {
        '/left/camera_info': calibration_to_camera_info(calibration.left, left_header),
        '/right/camera_info': calibration_to_camera_info(calibration.right, right_header),
        '/ground_truth/target': ground_truth_to_target(frame.ground_truth, header(WORLD_FRAME)),
        '/ground_truth/object': ground_truth_to_marker(frame.ground_truth, header(WORLD_FRAME)),
        '/left/image_raw': array_to_image(frame.left, frame.encoding, left_header),
        '/right/image_raw': array_to_image(frame.right, frame.encoding, right_header),
    }
    return [(topic, serialize_message(messages[topic])) for topic in TOPICS]


def rig_message(rig: StereoRig, calibration: StereoCalibration, stamp_ns: int) -> bytes:
    """Return the CDR bytes of /tf_static: world -> left optical -> right optical frame."""
    left = chapter_left_camera_transform(rig, WORLD_FRAME, calibration.left.frame_id)
    right = right_camera_transform(calibration, calibration.left.frame_id,
                                   calibration.right.frame_id)
    return bytes(serialize_message(transforms_to_tf_message([left, right], _stamp(stamp_ns))))


def write_scene_bag(settings: SceneBagSettings, command: str = '') -> int:
    """Render every scene of `settings` into a new bag; return the number of scenes.

    Messages of one scene share the header stamp; their bag timestamps are 1 us apart in the
    order of TOPICS, so every reader replays them in the same order.

    Raises:
        BagError: When the output exists.
        SceneError: When a scene cannot be placed in view of the rig.
    """
    plan = settings.scene_plan()
    drawn_rig = (None if settings.distribution_rig is None
                 else draw_rig(settings.distribution_rig))
    camera = settings.camera if drawn_rig is None else drawn_rig.camera
    rig = settings.rig if drawn_rig is None else drawn_rig.rig
    with SceneRenderer(camera=camera, rig=rig, sensor=settings.sensor,
                       encoding=settings.encoding) as renderer, \
            BagWriter(settings.output, compression=settings.compression,
                      compression_level=settings.compression_level) as bag:
        for topic, msgtype in RIG_TOPICS.items():
            bag.add_topic(topic, msgtype, (make_qos(depth=1, transient_local=True),))
        for topic, msgtype in TOPICS.items():
            bag.add_topic(topic, msgtype)
        if command:
            bag.set_custom_data('render_scenes', command)
        start_ns = round(settings.start_time_s * 1e9)
        bag.write('/tf_static', start_ns, canonical_cdr(
            rig_message(rig, renderer.calibration, start_ns), RIG_TOPICS['/tf_static'],
            bag.typestore))
        for index, (scene_seed, object_type) in enumerate(plan):
            if drawn_rig is None:
                frame = renderer.render(random_scene(scene_seed, object_type, rig=rig,
                                                     camera=camera))
            else:
                drawn = draw_scene('bag', scene_seed, drawn_rig, object_type)
                frame = renderer.render(drawn.scene, lighting=drawn.lighting,
                                        sensor=drawn.sensor())
            stamp_ns = start_ns + round(index * settings.period_s * 1e9)
            for order, (topic, data) in enumerate(frame_messages(frame, stamp_ns)):
                bag.write(topic, stamp_ns + 1000 * order,
                          canonical_cdr(data, TOPICS[topic], bag.typestore))
    return len(plan)


def build_parser() -> argparse.ArgumentParser:
    """Return the command-line parser of render_scenes."""
    parser = argparse.ArgumentParser(
        prog='render_scenes', description=__doc__.split('\n\n', 1)[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument('-o', '--output', required=True, type=Path,
                        help='bag directory to create (must not exist)')
    parser.add_argument('--types', nargs='+', default=[t.value for t in OBJECT_TYPES],
                        choices=[t.value for t in OBJECT_TYPES], help='object types')
    parser.add_argument('--scenes-per-type', type=int, default=3)
    parser.add_argument('--seed', type=int, default=0,
                        help=f'scene k uses seed * {SEED_STRIDE} + k')
    camera = parser.add_argument_group('cameras')
    camera.add_argument('--width', type=int, default=640, help='[px]')
    camera.add_argument('--height', type=int, default=480, help='[px]')
    camera.add_argument('--fov', type=float, default=45.0, help='vertical field of view [deg]')
    camera.add_argument('--encoding', choices=RENDER_ENCODINGS, default='rgb8')
    rig = parser.add_argument_group('rig (StereoRig, the chapter alpha, theta, z0)')
    defaults = StereoRig()
    rig.add_argument('--baseline', type=float, default=defaults.baseline_m, help='[m]')
    rig.add_argument('--alpha', type=float, default=defaults.alpha_deg, help='about x [deg]')
    rig.add_argument('--theta', type=float, default=defaults.theta_deg, help='about z [deg]')
    rig.add_argument('--x0', type=float, default=defaults.x0_m, help='[m]')
    rig.add_argument('--y0', type=float, default=defaults.y0_m, help='[m]')
    rig.add_argument('--z0', type=float, default=defaults.z0_m, help='[m]')
    rig.add_argument('--vergence', type=float, default=defaults.vergence_deg,
                     help='total toe-in [deg]')
    sensor = parser.add_argument_group('sensors')
    sensor.add_argument('--noise', type=float, default=0.0,
                        help='Gaussian noise std [grey levels]')
    sensor.add_argument('--right-gain', type=float, default=1.0)
    sensor.add_argument('--right-offset', type=float, default=0.0, help='[grey levels]')
    sensor.add_argument('--distortion', type=float, nargs=5, default=[0.0] * 5,
                        metavar=('K1', 'K2', 'P1', 'P2', 'K3'), help='plumb_bob coefficients')
    distribution = parser.add_argument_group(
        'scene distribution (simulation/scene_distribution.py)')
    distribution.add_argument(
        '--distribution-rig', type=int, default=None, metavar='INDEX',
        help="rig INDEX of the distribution's rig pool; each scene then draws its textures, "
        'light, noise and right gain/offset from the distribution (draw_scene with seed '
        'seed * 10000 + k); replaces the camera, rig and sensor options')
    distribution.add_argument(
        '--chain-params', type=Path, default=None, metavar='TEMPLATE',
        help='with --distribution-rig: write OUTPUT/chain_params.yaml, TEMPLATE (e.g. '
        "chain/demo_params.yaml) with the rig's correlation_node disparity search and "
        'fuzzy_best_point_node rig.* parameters')
    output = parser.add_argument_group('bag')
    output.add_argument('--compression', choices=COMPRESSIONS, default='zstd',
                        help='MCAP chunk compression')
    output.add_argument('--compression-level', type=int, default=19, help='zstd level')
    output.add_argument('--period', type=float, default=1.0, help='time between scenes [s]')
    output.add_argument('--start-time', type=float, default=1_700_000_000.0,
                        help='stamp of the first scene [s since the epoch]')
    return parser


def settings_from_arguments(args: argparse.Namespace) -> SceneBagSettings:
    """Return the settings the parsed command line asks for."""
    return SceneBagSettings(
        output=args.output,
        object_types=tuple(ObjectType(name) for name in args.types),
        scenes_per_type=args.scenes_per_type, seed=args.seed,
        camera=SimulatedCamera(width=args.width, height=args.height,
                               vertical_fov_deg=args.fov),
        rig=StereoRig(baseline_m=args.baseline, alpha_deg=args.alpha, theta_deg=args.theta,
                      x0_m=args.x0, y0_m=args.y0, z0_m=args.z0, vergence_deg=args.vergence),
        sensor=SensorModel(noise_std=args.noise, right_gain=args.right_gain,
                           right_offset=args.right_offset, distortion=tuple(args.distortion)),
        encoding=args.encoding, compression=args.compression,
        compression_level=args.compression_level, period_s=args.period,
        start_time_s=args.start_time, distribution_rig=args.distribution_rig)


def chain_parameters(template: dict[str, Any], rig_index: int) -> dict[str, Any]:
    """Return `template` (a chain parameter file) set up for rig `rig_index` of the pool.

    correlation_node and fuzzy_best_point_node get the rig's pose (rig.*), and
    correlation_node derives its disparity search from it (disparity_range 0, the node's
    default, replacing a fixed range of the template); everything else stays as in the
    template.
    """
    drawn = draw_rig(rig_index)
    pose = {name: float(getattr(drawn.rig, name)) for name in (
        'baseline_m', 'alpha_deg', 'theta_deg', 'x0_m', 'y0_m', 'z0_m', 'vergence_deg')}
    result = copy.deepcopy(template)
    correlation = result.setdefault('correlation_node', {}).setdefault('ros__parameters', {})
    correlation.pop('min_disparity', None)
    correlation['disparity_range'] = 0
    correlation['rig'] = dict(pose)
    fuzzy = result.setdefault('fuzzy_best_point_node', {}).setdefault('ros__parameters', {})
    fuzzy['rig'] = dict(pose)
    return result


def describe_command(arguments: Sequence[str]) -> str:
    """Return the command line without its output path (so it does not change the content)."""
    kept: list[str] = []
    skip = False
    for argument in arguments:
        if skip:
            skip = False
        elif argument in ('-o', '--output'):
            skip = True
        elif not argument.startswith(('-o', '--output=')):
            kept.append(argument)
    return shlex.join(['render_scenes', *kept, '-o', 'BAG'])


def main(argv: Sequence[str] | None = None) -> int:
    """Render the scenes the command line asks for and print the bag's summary."""
    arguments = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(arguments)
    if args.scenes_per_type < 1 or args.period <= 0.0:
        raise SystemExit('render_scenes: --scenes-per-type must be >= 1 and --period > 0')
    if args.chain_params is not None and args.distribution_rig is None:
        raise SystemExit('render_scenes: --chain-params needs --distribution-rig')
    try:
        write_scene_bag(settings_from_arguments(args), command=describe_command(arguments))
    except (BagError, SceneError) as error:
        raise SystemExit(f'render_scenes: {error}') from None
    if args.chain_params is not None:
        template = yaml.safe_load(args.chain_params.read_text())
        parameters = chain_parameters(template, args.distribution_rig)
        header = (f'# Chain parameters for this bag: {args.chain_params.name} with rig '
                  f"{args.distribution_rig} of the scene distribution's pool\n"
                  f'# ({draw_rig(args.distribution_rig).describe()}), written by\n'
                  f'#   {describe_command(arguments)}\n')
        (args.output / 'chain_params.yaml').write_text(
            header + yaml.safe_dump(parameters, sort_keys=False))
    print(format_info(read_info(args.output)))
    return 0


if __name__ == '__main__':
    sys.exit(main())
