"""Transform <-> geometry_msgs/TransformStamped and tf2_msgs/TFMessage (/tf and /tf_static)."""

from __future__ import annotations

from builtin_interfaces.msg import Time
from geometry_msgs.msg import TransformStamped

from stereo_fuzzy_perception.core.frame_transforms import Transform
from tf2_msgs.msg import TFMessage


def transform_to_message(transform: Transform, stamp: Time) -> TransformStamped:
    """Return a geometry_msgs/TransformStamped (parent frame in the header) of `transform`."""
    msg = TransformStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = transform.frame_id
    msg.child_frame_id = transform.child_frame_id
    msg.transform.translation.x, msg.transform.translation.y, msg.transform.translation.z = (
        float(value) for value in transform.translation)
    rotation = msg.transform.rotation
    rotation.x, rotation.y, rotation.z, rotation.w = (float(value)
                                                      for value in transform.rotation)
    return msg


def transforms_to_tf_message(transforms: list[Transform], stamp: Time) -> TFMessage:
    """Return a tf2_msgs/TFMessage holding `transforms`, all stamped `stamp`."""
    return TFMessage(transforms=[transform_to_message(t, stamp) for t in transforms])


def transform_from_message(msg: TransformStamped) -> Transform:
    """Return the Transform of a TransformStamped (not validated: see Transform.problem())."""
    translation, rotation = msg.transform.translation, msg.transform.rotation
    return Transform(msg.header.frame_id, msg.child_frame_id,
                     (float(translation.x), float(translation.y), float(translation.z)),
                     (float(rotation.x), float(rotation.y), float(rotation.z),
                      float(rotation.w)))


def tf_message_to_transforms(msg: TFMessage) -> list[Transform]:
    """Return the usable transforms of a TFMessage; those with a problem() are left out."""
    transforms = [transform_from_message(item) for item in msg.transforms]
    return [transform for transform in transforms if transform.problem() is None]

