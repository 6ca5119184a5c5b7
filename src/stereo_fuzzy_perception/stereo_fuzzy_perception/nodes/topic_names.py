"""The chain's topic names, once. ROS-free, so launch descriptions, tools and tests share them.

Every name a node uses is relative and carries no namespace of its own, as stereo_image_proc's
`left/image_rect`, `disparity` and `points2` do: a node pushed into a namespace (`-r
__ns:=/stereo`, launch_ros' `namespace=` or PushRosNamespace) or remapped (`-r pair:=/rig1/pair`)
takes all of its topics along, and nothing resolves to a doubled prefix such as
`/stereo/stereo/pair`. The chain description (launch/chain_processes.yaml) starts the camera-rig
nodes in STEREO_NAMESPACE, so the default chain has `/stereo/left/image_raw`, `/stereo/pair`,
`/stereo/matches`, `/stereo/points` and `/stereo/disparity`, and fuzzy_best_point_node at the
root, its `matches` remapped there, so `/best_point` is where gantry_driver_node listens.
Only /diagnostics and /tf_static are absolute: they are global by ROS convention.
"""

from __future__ import annotations

# The namespace the chain description starts the camera-rig nodes in by default.
STEREO_NAMESPACE = 'stereo'

# stereo_camera_node out, stereo_sync_node in: a calibrated stereo camera driver's topics.
LEFT_IMAGE = 'left/image_raw'
LEFT_CAMERA_INFO = 'left/camera_info'
RIGHT_IMAGE = 'right/image_raw'
RIGHT_CAMERA_INFO = 'right/camera_info'
CAMERA_TOPICS = (LEFT_IMAGE, LEFT_CAMERA_INFO, RIGHT_IMAGE, RIGHT_CAMERA_INFO)

# stereo_sync_node -> correlation_node -> fuzzy_best_point_node
PAIR = 'pair'
MATCHES = 'matches'
POINTS = 'points'
DISPARITY = 'disparity'

# fuzzy_best_point_node out
BEST_POINT = 'best_point'
DECISION = 'best_point/decision'
MARKERS = 'best_point/markers'

# Per-pair timing of each node, next to its output, sent only while subscribed (pair_timing.py)
PAIR_TIMING = 'pair/timing'
MATCHES_TIMING = 'matches/timing'
DECISION_TIMING = 'best_point/timing'

DIAGNOSTICS = '/diagnostics'
TF_STATIC = '/tf_static'


def in_namespace(namespace: str, name: str) -> str:
    """Return `name` pushed into `namespace` as rcl resolves it ('' = the root).

    Args:
        namespace: A namespace, absolute or relative to the root ('stereo', '/stereo', '').
        name: A relative topic name ('pair').

    Returns:
        The absolute name ('/stereo/pair').
    """
    parts = [part for part in (*namespace.split('/'), *name.split('/')) if part]
    return '/' + '/'.join(parts)
