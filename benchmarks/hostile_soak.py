"""Soak the three perception processes with a stream of good and hostile inputs (issue #15).

For `--minutes` it publishes camera sets at `--rate` [Hz] into stereo_sync_node (a share of them
spoiled: unusable calibrations, oversized images, unsupported encodings), and every few seconds
sets a hostile parameter on a node (files that are FIFOs, devices, malformed YAML or .npy
weights; max_rate_hz flips). At the end one last set exposes losses at the tail, and it prints:
node deaths, best points published that are non-finite or outside the workspace box, every
parameter change refused without a reason, and every loss-accounting identity that does not hold
(the same identities as tests/hostile/test_hostile_loss_accounting.py). All must be zero.

    source scripts/env.sh
    nice python benchmarks/hostile_soak.py --minutes 30
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO_ROOT), str(REPO_ROOT / 'tests' / 'support')]

from chain.processes import ProcessGroup, wait_for  # noqa: E402
from chain.ros_domains import exported_domain_id  # noqa: E402

INPUTS = ('left/image_raw', 'left/camera_info', 'right/image_raw', 'right/camera_info')
CORRELATION_DROPS = ('superseded', 'image_too_large', 'calibration', 'size_mismatch',
                     'encoding', 'matcher_input', 'opencv', 'internal')
WORKSPACE = ((0.0, 0.0, 0.0), (0.4, 0.3, 0.2))  # fuzzy_best_point_node's default box [m]


def hostile_files(folder: Path) -> list[tuple[str, str, str]]:
    """(node, parameter, value) of hostile parameter changes, files made in `folder`."""
    fifo = folder / 'rules.fifo'
    os.mkfifo(fifo)
    npy = folder / 'weights.npy'
    np.save(npy, np.zeros(3))
    bad_yaml = folder / 'bad.yaml'
    bad_yaml.write_text('name: x\nmembership_functions: [{name: [1], points: [0, 1, 2]}]\n'
                        'rules: [{name: r, area: 1, if: [less], then: {areas: [1]}}]\n')
    return [('fuzzy_best_point_node', 'rule_base_file', str(fifo)),
            ('fuzzy_best_point_node', 'rule_base_file', '/dev/zero'),
            ('fuzzy_best_point_node', 'rule_base_file', str(bad_yaml)),
            ('fuzzy_best_point_node', 'network_file', str(npy)),
            ('fuzzy_best_point_node', 'selector', 'neural_network'),
            ('fuzzy_best_point_node', 'selector', 'fuzzy_fitted'),
            ('correlation_node', 'max_rate_hz', 0.001),
            ('correlation_node', 'max_rate_hz', 0.0),
            ('stereo_sync_node', 'max_image_pixels', 1000),
            ('stereo_sync_node', 'max_image_pixels', 4096 * 3072)]


def camera_set(stamp: int, kind: int) -> dict:
    """The four inputs of one set; kind 0-5 good, 6 spoiled calibration, 7 oversized."""
    from hostile_messages import camera_inputs, spoiled_right_cameras

    if kind == 6:
        spoiled = spoiled_right_cameras()
        return camera_inputs(stamp, right=spoiled[stamp % len(spoiled)][1])
    if kind == 7:
        return camera_inputs(stamp, size=(40000, 8))
    return camera_inputs(stamp)


def main() -> int:
    """Run the soak and print its figures; exit 1 when any must-be-zero figure is not."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--minutes', type=float, default=30.0)
    parser.add_argument('--rate', type=float, default=10.0, help='camera sets per second')
    parser.add_argument('--log-dir', type=Path, default=REPO_ROOT / 'output' / 'hostile_soak')
    options = parser.parse_args()
    with exported_domain_id(), tempfile.TemporaryDirectory() as folder:
        return soak(options, Path(folder))


def soak(options: argparse.Namespace, folder: Path) -> int:
    """Start the processes, run the stream, report."""
    import rclpy
    from geometry_msgs.msg import PointStamped
    from hostile_probe import HostileProbe
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import CameraInfo, Image
    from stereo_fuzzy_perception.nodes import qos

    group = ProcessGroup(options.log_dir, env=dict(os.environ))
    processes = {
        'stereo_sync_node': group.start_node('stereo_fuzzy_perception', 'stereo_sync_node',
                                             '-p', 'input_reliability:=reliable'),
        'correlation_node': group.start_node('stereo_fuzzy_perception', 'correlation_node',
                                             '-p', 'window_size:=5', '-p', 'disparity_range:=16'),
        'fuzzy_best_point_node': group.start_node('stereo_fuzzy_perception',
                                                  'fuzzy_best_point_node'),
    }
    rclpy.init()
    executor = SingleThreadedExecutor()
    try:
        probes = {name: HostileProbe(rclpy.get_default_context(), process, name, executor)
                  for name, process in processes.items()}
        sync = probes['stereo_sync_node']
        bad_points: list[tuple[float, float, float]] = []
        points = [0]

        def on_point(msg: PointStamped) -> None:
            points[0] += 1
            xyz = (msg.point.x, msg.point.y, msg.point.z)
            if not all(math.isfinite(v) and lo <= v <= hi
                       for v, lo, hi in zip(xyz, *WORKSPACE, strict=True)):
                bad_points.append(xyz)

        sync.node.create_subscription(PointStamped, 'best_point', on_point, qos.RESULTS)
        publishers = {topic: sync.node.create_publisher(
            Image if 'image' in topic else CameraInfo, topic, qos.RESULTS) for topic in INPUTS}
        wait_for(lambda: sync.node.count_subscribers('pair') > 0
                 and sync.node.count_subscribers('matches') > 0, 180.0,
                 'the nodes to subscribe', lambda t: executor.spin_once(timeout_sec=t), group)
        changes = hostile_files(folder)
        silent_refusals = changes_made = 0
        end = time.monotonic() + 60.0 * options.minutes
        stamp = 0
        next_change = time.monotonic() + 2.0
        while time.monotonic() < end and not group.exited():
            stamp += 1
            for topic, message in camera_set(stamp, stamp % 8).items():
                publishers[topic].publish(message)
            if time.monotonic() >= next_change:
                node, name, value = changes[changes_made % len(changes)]
                successful, reason = probes[node].set_parameter(name, value)
                silent_refusals += int(not successful and not reason)
                changes_made += 1
                next_change = time.monotonic() + 2.0
            deadline = time.monotonic() + 1.0 / options.rate
            while time.monotonic() < deadline:
                executor.spin_once(timeout_sec=max(0.0, deadline - time.monotonic()))
        for node, name, value in (('correlation_node', 'max_rate_hz', 0.0),
                                  ('stereo_sync_node', 'max_image_pixels', 4096 * 3072)):
            probes[node].set_parameter(name, value)
        fuzzy = probes['fuzzy_best_point_node']
        before = count(fuzzy, 'matches received')
        for topic, message in camera_set(stamp + 1, 0).items():  # the tail marker
            publishers[topic].publish(message)
        broken: list[str] = []
        try:
            wait_for(lambda: count(fuzzy, 'matches received') > before
                     and not unaccounted(probes), 120.0, 'the counts to agree',
                     lambda t: executor.spin_once(timeout_sec=t), group)
        except (TimeoutError, RuntimeError) as error:
            broken = unaccounted(probes) or [str(error).splitlines()[0]]
        deaths = [process.name for process in group.exited()]
        print(f'{changes_made} hostile parameter changes')
        report(probes, stamp + 1, points[0], bad_points, silent_refusals, broken, deaths,
               options)
        return 1 if deaths or bad_points or silent_refusals or broken else 0
    finally:
        executor.shutdown()
        rclpy.try_shutdown()
        group.stop_all()


def count(probe, key: str) -> int:
    """The latest /diagnostics value of `key` from the probe's node, as an integer."""
    value = probe.diagnostic_value(key)
    return int(value) if value is not None else 0


def unaccounted(probes: dict) -> list[str]:
    """Return the loss-accounting identities the latest reports break."""
    sync, correlation = probes['stereo_sync_node'], probes['correlation_node']
    fuzzy = probes['fuzzy_best_point_node']
    received, matched = count(correlation, 'pair received'), count(
        correlation, 'pairs processed')
    arrived = count(fuzzy, 'matches received')
    identities = {
        'sync in = out + dropped': (count(sync, 'pairs in'),
                                    count(sync, 'pairs out') + count(sync, 'pairs dropped')),
        'correlation received + lost = sync out':
            (received + count(correlation, 'pair lost (sequence gaps)')
             + count(correlation, 'pair sent before the first received'),
             count(sync, 'pairs out')),
        'correlation processed + dropped + waiting = received':
            (matched + count(correlation, 'pairs waiting') + sum(
                count(correlation, f'dropped {reason}') for reason in CORRELATION_DROPS),
             received),
        'fuzzy received + lost = correlation processed':
            (arrived + count(fuzzy, 'matches lost (sequence gaps)')
             + count(fuzzy, 'matches sent before the first received'), matched),
        'fuzzy decisions = received':
            (count(fuzzy, 'decisions made') + count(fuzzy, 'decisions refused'), arrived)}
    return [f'{name}: {a} != {b}' for name, (a, b) in identities.items() if a != b]


def report(probes: dict, sets: int, points: int, bad_points: list, silent_refusals: int,
           broken: list[str], deaths: list[str], options: argparse.Namespace) -> None:
    """Print the soak's figures."""
    sync, correlation = probes['stereo_sync_node'], probes['correlation_node']
    fuzzy = probes['fuzzy_best_point_node']
    print(f'hostile soak: {options.minutes:g} min, {sets} camera sets at {options.rate:g} Hz')
    print(f'  stereo_sync_node: received {count(sync, "received left/image_raw")} left images, '
          f'{count(sync, "pairs in")} sets in, {count(sync, "pairs out")} pairs out, '
          f'{count(sync, "pairs dropped")} dropped')
    print(f'  correlation_node: {count(correlation, "pair received")} received, '
          f'{count(correlation, "pair lost (sequence gaps)")} lost, '
          f'{count(correlation, "pairs processed")} processed, '
          + ', '.join(f'{reason} {count(correlation, f"dropped {reason}")}'
                      for reason in CORRELATION_DROPS))
    print(f'  fuzzy_best_point_node: {count(fuzzy, "matches received")} received, '
          f'{count(fuzzy, "matches lost (sequence gaps)")} lost, '
          f'{count(fuzzy, "decisions made")} made, {count(fuzzy, "decisions refused")} '
          f'refused; {points} best points published')
    print(f'node deaths: {len(deaths)} {deaths or ""}')
    print(f'best points non-finite or outside the workspace: {len(bad_points)}')
    print(f'parameter changes refused without a reason: {silent_refusals}')
    print(f'accounting identities broken: {len(broken)} {broken or ""}')


if __name__ == '__main__':
    sys.exit(main())
