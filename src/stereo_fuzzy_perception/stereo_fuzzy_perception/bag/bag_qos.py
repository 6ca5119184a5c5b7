"""QoS between bags (rosbags Qos, as recorded in offered_qos_profiles) and rclpy QoSProfile.

The player offers what the recorded publishers offered (reliability and durability), keep last
at least 10; the recorder subscribes with what every current publisher can serve, as
`ros2 bag record` does.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import yaml
from rclpy.duration import Duration
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    LivelinessPolicy,
    QoSProfile,
    ReliabilityPolicy,
)
from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)

from stereo_fuzzy_perception.bag.bag_format import BagError, absolute_topic

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


_POLICY_TYPES = {'history': HistoryPolicy, 'reliability': ReliabilityPolicy,
                 'durability': DurabilityPolicy, 'liveliness': LivelinessPolicy}
_DURATIONS = ('deadline', 'lifespan', 'liveliness_lease_duration')


def _policy(kind: str, value: object, where: str) -> object:
    policy_type = _POLICY_TYPES[kind]
    try:
        if isinstance(value, int) and not isinstance(value, bool):
            return policy_type(value)
        return policy_type[str(value).upper()]
    except (KeyError, ValueError):
        names = ', '.join(member.name.lower() for member in policy_type)
        raise BagError(f'{where}: {kind} {value!r} is not one of {names}') from None


def _duration(value: object, where: str) -> Duration:
    if isinstance(value, dict) and set(value) <= {'sec', 'nsec'}:
        try:
            return Duration(seconds=int(value.get('sec', 0)),
                            nanoseconds=int(value.get('nsec', 0)))
        except (TypeError, ValueError):
            pass
    raise BagError(f'{where}: expected {{sec: S, nsec: N}}, got {value!r}')


def load_qos_overrides(path: Path | str) -> dict[str, QoSProfile]:
    """Read a QoS override file in rosbag2's format (`--qos-profile-overrides-path`).

    Each top-level key is a topic; its fields are those of a QoS profile: history, depth,
    reliability, durability (names such as keep_last, best_effort, transient_local), deadline,
    lifespan and liveliness_lease_duration as {sec, nsec}, liveliness,
    avoid_ros_namespace_conventions. Fields not given keep rclpy's defaults (keep last 10,
    reliable, volatile).

    Raises:
        BagError: When the file cannot be read, or a field is unknown or has a bad value; the
            message names the file, the topic and the field.
    """
    file = Path(path)
    try:
        document = yaml.safe_load(file.read_text())
    except (OSError, yaml.YAMLError) as error:
        raise BagError(f'{file}: cannot read QoS overrides ({error})') from None
    if not isinstance(document, dict):
        raise BagError(f'{file}: expected a mapping of topic names to QoS profiles')
    overrides = {}
    for topic, fields in document.items():
        where = f'{file}: {topic}'
        if not isinstance(fields, dict):
            raise BagError(f'{where}: expected a mapping of QoS fields')
        values: dict[str, object] = {}
        for name, value in fields.items():
            if name in _POLICY_TYPES:
                values[name] = _policy(name, value, where)
            elif name in _DURATIONS:
                values[name] = _duration(value, f'{where}.{name}')
            elif name == 'depth':
                if not isinstance(value, int) or isinstance(value, bool) or value < 0:
                    raise BagError(f'{where}: depth must be a non-negative integer, '
                                   f'got {value!r}')
                values[name] = value
            elif name == 'avoid_ros_namespace_conventions':
                values[name] = bool(value)
            else:
                raise BagError(f'{where}: unknown QoS field {name!r}')
        values.setdefault('depth', PLAYBACK_MIN_DEPTH)
        values.setdefault('history', HistoryPolicy.KEEP_LAST)
        overrides[absolute_topic(str(topic))] = QoSProfile(**values)
    return overrides
