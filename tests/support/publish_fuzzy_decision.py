"""Publish one FuzzyDecision with known contents once a subscriber is matched (test helper)."""

import rclpy
from geometry_msgs.msg import Point
from rclpy.qos import QoSProfile, ReliabilityPolicy

from stereo_fuzzy_msgs.msg import FuzzyDecision


def known_decision() -> FuzzyDecision:
    """Return the decision the round-trip test expects, with every kind of field filled."""
    decision = FuzzyDecision()
    decision.header.frame_id = 'world'
    decision.header.stamp.sec = 1234
    decision.selector = 'fuzzy_fitted'
    decision.has_best_point = True
    decision.status = FuzzyDecision.STATUS_OK
    decision.best_point_world = Point(x=0.1, y=-0.2, z=0.03)
    decision.border_points = [Point(x=float(k), y=2.0 * k, z=0.5) for k in range(4)]
    decision.border_distances = [0.5 * k for k in range(6)]
    decision.area_point_counts = [10, 20, 30, 40]
    decision.ratio = [0.9, 1.0, 1.1, 1.2]
    decision.rule_names = [f'rule_{k}' for k in range(12)]
    decision.firing_strengths = [k / 12.0 for k in range(12)]
    return decision


def main() -> None:
    """Publish the known decision on `decision` and exit."""
    rclpy.init()
    node = rclpy.create_node('decision_publisher')
    publisher = node.create_publisher(
        FuzzyDecision, 'decision', QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    while publisher.get_subscription_count() == 0:
        rclpy.spin_once(node, timeout_sec=0.05)
    publisher.publish(known_decision())
    # Stay until the subscriber has gone, so a reliable message is never dropped on exit.
    while publisher.get_subscription_count() > 0:
        rclpy.spin_once(node, timeout_sec=0.05)
    node.destroy_node()
    rclpy.shutdown()


if __name__ == '__main__':
    main()
