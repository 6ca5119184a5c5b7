#!/usr/bin/env python3
"""Benchmark one DDS hop between two processes: Fast DDS's default transports against the
package's profile (src/stereo_fuzzy_perception/config/fastdds_large_messages.xml).

For each message size, a publisher process sends mono8 images at a fixed rate on a reliable
topic (depth 3, as the chain's) and a receiver process measures header stamp -> callback
(one host, one clock); both run once without FASTRTPS_DEFAULT_PROFILES_FILE (the reference) and
once with the profile, back to back.

    source scripts/env.sh
    python benchmarks/dds_hop_benchmark.py
    python benchmarks/dds_hop_benchmark.py --sizes 614400 --messages 600

Prints a markdown table of p50 / p99 / max [ms] per size and transport set.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from chain.ros_domains import reserved_domain_id  # noqa: E402

PROFILE = ROOT / 'src' / 'stereo_fuzzy_perception' / 'config' / 'fastdds_large_messages.xml'
VARIABLE = 'FASTRTPS_DEFAULT_PROFILES_FILE'
WIDTH = 640
WARM_UP = 30
"""Messages sent before the measured ones (discovery and first allocations)."""

# one 640x480 image; a stereo pair; a StereoMatches message at the demo's point_stride 3
DEFAULT_SIZES = (640 * 480, 2 * 640 * 480, 1_300_000)


def run_peer(role: str, size: int, messages: int, rate: float) -> int:
    """One side of the hop (started by main as a child process)."""
    import numpy as np
    import rclpy
    from rclpy.node import Node
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Image

    qos = QoSProfile(depth=3, reliability=ReliabilityPolicy.RELIABLE,
                     history=HistoryPolicy.KEEP_LAST)
    rclpy.init()
    node = Node(f'dds_hop_{role}')
    total = messages + WARM_UP
    try:
        if role == 'publish':
            publisher = node.create_publisher(Image, 'dds_hop', qos)
            message = Image(height=max(1, size // WIDTH), width=WIDTH, encoding='mono8',
                            step=WIDTH)
            message.data = np.random.default_rng(0).integers(
                0, 255, message.height * WIDTH, dtype=np.uint8).tobytes()
            while publisher.get_subscription_count() == 0:
                rclpy.spin_once(node, timeout_sec=0.05)
            next_at = time.monotonic()
            for _ in range(total):
                message.header.stamp = node.get_clock().now().to_msg()
                publisher.publish(message)
                next_at += 1.0 / rate
                time.sleep(max(0.0, next_at - time.monotonic()))
            # stay until the receiver has everything (it ends first)
            while publisher.get_subscription_count() > 0:
                rclpy.spin_once(node, timeout_sec=0.05)
            return 0
        latencies: list[float] = []

        def on_image(image: Image) -> None:
            stamp = image.header.stamp.sec * 1_000_000_000 + image.header.stamp.nanosec
            latencies.append((node.get_clock().now().nanoseconds - stamp) / 1e6)

        node.create_subscription(Image, 'dds_hop', on_image, qos)
        deadline = time.monotonic() + total / rate + 60.0
        while len(latencies) < total and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.1)
        print(json.dumps({'latencies_ms': latencies[WARM_UP:], 'received': len(latencies)}),
              flush=True)
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def measure(size: int, messages: int, rate: float, profile: bool) -> dict:
    """Run one publisher / receiver pair; return the receiver's report."""
    environment = {key: value for key, value in os.environ.items() if key != VARIABLE}
    if profile:
        environment[VARIABLE] = str(PROFILE)
    with reserved_domain_id() as domain_id:
        environment['ROS_DOMAIN_ID'] = str(domain_id)
        command = [sys.executable, __file__, '--peer']
        arguments = [str(size), str(messages), str(rate)]
        receiver = subprocess.Popen([*command, 'receive', *arguments], env=environment,
                                    stdout=subprocess.PIPE, text=True)
        publisher = subprocess.Popen([*command, 'publish', *arguments], env=environment,
                                     stdout=subprocess.DEVNULL)
        output, _ = receiver.communicate()
        publisher.wait(timeout=30.0)
    return json.loads(output.strip().splitlines()[-1])


def main() -> int:
    if len(sys.argv) > 1 and sys.argv[1] == '--peer':
        role, size, messages, rate = sys.argv[2], *sys.argv[3:6]
        return run_peer(role, int(size), int(messages), float(rate))
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--sizes', type=int, nargs='+', default=list(DEFAULT_SIZES),
                        help='message sizes [bytes]')
    parser.add_argument('--messages', type=int, default=300, help='measured messages per run')
    parser.add_argument('--rate', type=float, default=30.0, help='messages per second')
    args = parser.parse_args()
    import numpy as np

    print(f'### One DDS hop, {args.messages} messages at {args.rate:g} Hz, reliable, depth 3 '
          f'(load average {os.getloadavg()[0]:.1f} before)')
    print()
    print('| message [bytes] | default transports p50 / p99 / max [ms] | '
          f'{PROFILE.name} p50 / p99 / max [ms] | received (default / profile) |')
    print('|---:|---:|---:|---:|')
    for size in args.sizes:
        cells, received = [], []
        for profile in (False, True):
            report = measure(size, args.messages, args.rate, profile)
            latencies = np.array(report['latencies_ms'])
            received.append(f'{len(latencies)} of {args.messages}')
            cells.append('none' if not len(latencies) else
                         f'{np.percentile(latencies, 50):.1f} / '
                         f'{np.percentile(latencies, 99):.1f} / {latencies.max():.1f}')
        print(f'| {size:,} | {cells[0]} | {cells[1]} | {" / ".join(received)} |', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
