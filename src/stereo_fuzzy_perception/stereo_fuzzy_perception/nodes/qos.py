"""QoS profiles by name, in one place (STYLE.md): what each kind of topic needs.

- Camera inputs: sensor data (best effort, keep last 5), as camera drivers publish them.
- Results (pairs, matches, best points, decisions): reliable, keep last 10.
- Diagnostics: reliable, keep last 10, as diagnostic_updater publishes them.
"""

from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)

CAMERA_INPUT = qos_profile_sensor_data

RESULTS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE)

DIAGNOSTICS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE)


def reliability_from_name(name: str) -> ReliabilityPolicy:
    """Map a parameter value ('reliable' or 'best_effort') to a ReliabilityPolicy."""
    return {'reliable': ReliabilityPolicy.RELIABLE,
            'best_effort': ReliabilityPolicy.BEST_EFFORT}[name]
