"""The QoS profiles more than one package uses, by name, so both ends of a topic agree.

- Results (pairs, matches, best points, decisions): reliable, keep last 10. The gantry driver
  takes best_point as its command with the same profile.
- Diagnostics: reliable, keep last 10, as diagnostic_updater publishes them.
- /tf: reliable, keep last 100, as tf2_ros' DynamicBroadcasterQoS.
- /tf_static: reliable, transient local (a late subscriber still gets the transforms); keep last
  1 to publish (every message holds all of a publisher's static transforms) and keep last 100
  to listen, as tf2_ros' StaticBroadcasterQoS and StaticListenerQoS.

Profiles only one package needs live in that package's `qos` module, beside these, built with
`reliable()` as these are.
"""

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy


def reliable(depth: int, *, transient_local: bool = False) -> QoSProfile:
    """Return a reliable, keep-last profile of `depth`; transient local or volatile."""
    durability = (DurabilityPolicy.TRANSIENT_LOCAL if transient_local
                  else DurabilityPolicy.VOLATILE)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE, durability=durability)


RESULTS = reliable(10)
DIAGNOSTICS = reliable(10)
TF = reliable(100)
TF_STATIC = reliable(100, transient_local=True)
TF_STATIC_BROADCAST = reliable(1, transient_local=True)
