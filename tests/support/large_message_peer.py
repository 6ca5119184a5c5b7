"""A peer for tests/test_dds_profile.py: publishes or receives large images on topic `large`.

    python large_message_peer.py publish BYTES      # until SIGINT, ten a second
    python large_message_peer.py receive BYTES N    # exits 0 after N intact messages

Each message's pixels are (index + k) % 251 for its index k and the number i in its frame_id,
so the receiver checks that every byte arrived, not only that a message did.
"""

from __future__ import annotations

import sys
import time

import numpy as np
import rclpy
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Image

QOS = QoSProfile(depth=3, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
WIDTH = 1000


def pixels(number: int, size: int) -> np.ndarray:
    return ((np.arange(size, dtype=np.int64) + number) % 251).astype(np.uint8)


def publish(node: Node, size: int) -> None:
    publisher = node.create_publisher(Image, 'large', QOS)
    number = 0
    while rclpy.ok():
        message = Image(height=size // WIDTH, width=WIDTH, encoding='mono8', step=WIDTH)
        message.header.frame_id = str(number)
        message.data = pixels(number, size).tobytes()
        publisher.publish(message)
        number += 1
        time.sleep(0.1)


def receive(node: Node, size: int, wanted: int) -> int:
    intact: list[int] = []
    broken: list[str] = []

    def on_image(message: Image) -> None:
        data = np.frombuffer(bytes(message.data), dtype=np.uint8)
        if len(data) == size and np.array_equal(data, pixels(int(message.header.frame_id), size)):
            intact.append(int(message.header.frame_id))
        else:
            broken.append(f'message {message.header.frame_id}: {len(data)} bytes')

    node.create_subscription(Image, 'large', on_image, QOS)
    while len(intact) < wanted and not broken:
        rclpy.spin_once(node, timeout_sec=0.5)
    print(f'received {len(intact)} intact, broken: {broken}', flush=True)
    return 0 if not broken else 1


def main() -> int:
    role, size = sys.argv[1], int(sys.argv[2])
    rclpy.init()
    node = Node(f'large_message_{role}')
    try:
        if role == 'publish':
            publish(node, size)
            return 0
        return receive(node, size, int(sys.argv[3]))
    except KeyboardInterrupt:  # the test's SIGINT: leave no shared-memory segment behind
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
