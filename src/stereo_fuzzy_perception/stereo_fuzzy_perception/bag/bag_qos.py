"""QoS between bags (rosbags Qos, as recorded in offered_qos_profiles) and rclpy QoSProfile.

The player offers what the recorded publishers offered (reliability and durability), keep last
at least 10; the recorder subscribes with what every current publisher can serve, as
`ros2 bag record` does.
"""

from __future__ import annotations

from collections.abc import Sequence

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)

PLAYBACK_MIN_DEPTH = 10


def _time(duration: object) -> QosTime:
    nanoseconds = int(getattr(duration, 'nanoseconds', 0))
    if nanoseconds >= 2**63 - 1 or nanoseconds < 0:
        nanoseconds = 0
    return QosTime(sec=nanoseconds // 1_000_000_000, nsec=nanoseconds % 1_000_000_000)


def profile_to_bag_qos(profile: QoSProfile) -> Qos:
    """Return the rosbags Qos recording `profile` (rmw enum values are shared)."""
    return Qos(
        history=QosHistory(int(profile.history)), depth=int(profile.depth),
        reliability=QosReliability(int(profile.reliability)),
        durability=QosDurability(int(profile.durability)),
        deadline=_time(profile.deadline), lifespan=_time(profile.lifespan),
        liveliness=QosLiveliness(int(profile.liveliness)),
        liveliness_lease_duration=_time(profile.liveliness_lease_duration),
        avoid_ros_namespace_conventions=bool(profile.avoid_ros_namespace_conventions))


def playback_profile(recorded: Sequence[Qos]) -> QoSProfile:
    """Return the QoS a player offers for a topic recorded with `recorded` profiles.

    Reliable unless every recorded publisher was best effort; transient local only when every
    one was; keep last max(recorded depth, 10). No recorded profile: reliable, volatile, 10.
    """
    reliability = ReliabilityPolicy.RELIABLE
    durability = DurabilityPolicy.VOLATILE
    depth = PLAYBACK_MIN_DEPTH
    if recorded:
        if all(q.reliability == QosReliability.BEST_EFFORT for q in recorded):
            reliability = ReliabilityPolicy.BEST_EFFORT
        if all(q.durability == QosDurability.TRANSIENT_LOCAL for q in recorded):
            durability = DurabilityPolicy.TRANSIENT_LOCAL
        depth = max([PLAYBACK_MIN_DEPTH] + [q.depth for q in recorded
                                              if q.history == QosHistory.KEEP_LAST])
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth, reliability=reliability,
                      durability=durability)


def recording_profile(offered: Sequence[QoSProfile]) -> QoSProfile:
    """Return the QoS a recorder subscribes with to receive from every offered publisher.

    Reliable and transient local only when every publisher offers it; keep last 10.
    """
    reliable = bool(offered) and all(
        p.reliability == ReliabilityPolicy.RELIABLE for p in offered)
    transient = bool(offered) and all(
        p.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in offered)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=PLAYBACK_MIN_DEPTH,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if transient else DurabilityPolicy.VOLATILE)
