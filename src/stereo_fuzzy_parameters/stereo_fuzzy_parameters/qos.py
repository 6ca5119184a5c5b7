"""The QoS profiles more than one package uses, by name, so both ends of a topic agree.

- Results (pairs, matches, best points, decisions): reliable, keep last 10. The gantry driver
  takes best_point as its command with the same profile.
- Diagnostics: reliable, keep last 10, as diagnostic_updater publishes them.
- /tf: reliable, keep last 100, as tf2_ros' DynamicBroadcasterQoS.
- /tf_static: reliable, transient local (a late subscriber still gets the transforms); keep last
  1 to publish (every message holds all of a publisher's static transforms) and keep last 100
  to listen, as tf2_ros' StaticBroadcasterQoS and StaticListenerQoS.

Profiles only one package needs live in that package's `qos` module, beside these.
"""

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

RESULTS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE)

DIAGNOSTICS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE)

TF = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=100, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE)

TF_STATIC = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=100, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL)

TF_STATIC_BROADCAST = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL)
