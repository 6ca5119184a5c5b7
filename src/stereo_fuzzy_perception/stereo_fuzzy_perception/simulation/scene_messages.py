"""The scene simulator's ground truth as ROS messages (for the bags it writes).

Kept beside the simulator, so the runtime nodes never import simulator types.
"""

from __future__ import annotations

import numpy as np
from geometry_msgs.msg import PointStamped
from std_msgs.msg import Header
from visualization_msgs.msg import Marker

from stereo_fuzzy_perception.simulation.scene_model import GroundTruth


def ground_truth_to_target(truth: GroundTruth, header: Header) -> PointStamped:
    """Return the target (centre of the object's top face) as a PointStamped in header's frame."""
    msg = PointStamped()
    msg.header = header
    msg.point.x, msg.point.y, msg.point.z = (float(v) for v in truth.target_world)
    return msg


def ground_truth_to_marker(truth: GroundTruth, header: Header) -> Marker:
    """Return the object as a Marker: CYLINDER or CUBE at its volume centre, scale = size [m].

    `ns` and `text` carry the object type (circle, cylinder, cubic_rectangle, cubic_square).
    """
    item = truth.scene_object
    msg = Marker()
    msg.header = header
    msg.ns = item.object_type.value
    msg.id = 0
    msg.type = Marker.CYLINDER if item.object_type.is_round else Marker.CUBE
    msg.action = Marker.ADD
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (
        float(v) for v in item.centre())
    msg.pose.orientation.z = float(np.sin(item.yaw_rad / 2.0))
    msg.pose.orientation.w = float(np.cos(item.yaw_rad / 2.0))
    msg.scale.x, msg.scale.y, msg.scale.z = item.size_x_m, item.size_y_m, item.height_m
    msg.color.r, msg.color.g, msg.color.b, msg.color.a = 0.9, 0.7, 0.3, 0.8
    msg.text = item.object_type.value
    return msg
