"""What reading and writing a bag share: the error type, recorded QoS profiles, topic names.

ROS-free: rosbags and the standard library only.
"""

from __future__ import annotations

from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)

_NO_TIME = QosTime(sec=0, nsec=0)


class BagError(RuntimeError):
    """A bag that cannot be read or written, with the path and the reason in the message."""


def make_qos(reliable: bool = True, depth: int = 10, transient_local: bool = False) -> Qos:
    """Return a rosbags QoS profile (keep last `depth`; default deadline, lifespan, liveliness)."""
    return Qos(
        history=QosHistory.KEEP_LAST, depth=depth,
        reliability=QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
        durability=QosDurability.TRANSIENT_LOCAL if transient_local else QosDurability.VOLATILE,
        deadline=_NO_TIME, lifespan=_NO_TIME, liveliness=QosLiveliness.AUTOMATIC,
        liveliness_lease_duration=_NO_TIME, avoid_ros_namespace_conventions=False)


DEFAULT_QOS = make_qos()


def absolute_topic(name: str) -> str:
    """Return `name` with a leading '/' (bags store absolute topic names)."""
    return name if name.startswith('/') else '/' + name
