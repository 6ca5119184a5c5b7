"""The one place that converts between ROS messages and this package's domain types.

Everything else in the package works on domain types. The conversions are grouped by message
family, and every public name is importable from here:

- `images`: sensor_msgs/Image <-> arrays (what cv_bridge does), CameraInfo <-> CameraCalibration,
  image size limits, header stamps.
- `point_cloud`: MatchedPoints <-> PointCloud2, with the cloud's layout checked first.
- `stereo`: the correlation stage's StereoPair, StereoMatches and DisparityImage.
- `decisions`: the fuzzy stage's BestPointDecision -> FuzzyDecision, PointStamped, MarkerArray.
- `transforms`: Transform <-> TransformStamped and TFMessage.
"""

from stereo_fuzzy_perception.nodes.conversions.decisions import (
    MARKER_NAMESPACE,
    best_point_to_point_stamped,
    decision_to_markers,
    decision_to_message,
)
from stereo_fuzzy_perception.nodes.conversions.images import (
    ImageSizeError,
    array_to_image,
    byte_array,
    calibration_to_camera_info,
    camera_info_to_calibration,
    check_image_layout,
    image_size_problem,
    image_to_array,
    stamp_to_ns,
)
from stereo_fuzzy_perception.nodes.conversions.point_cloud import (
    MATCH_FIELDS,
    CloudLayoutError,
    check_cloud_layout,
    cloud_to_matched_points,
    matched_points_to_cloud,
)
from stereo_fuzzy_perception.nodes.conversions.stereo import (
    check_pair_size,
    disparity_image_message,
    stereo_matches_colour,
    stereo_matches_image,
    stereo_matches_matcher,
    stereo_matches_message,
    stereo_pair_to_domain,
    stereo_pair_with_colour,
)
from stereo_fuzzy_perception.nodes.conversions.transforms import (
    tf_message_to_transforms,
    transform_from_message,
    transform_to_message,
    transforms_to_tf_message,
)

__all__ = [
    'MARKER_NAMESPACE',
    'MATCH_FIELDS',
    'CloudLayoutError',
    'ImageSizeError',
    'array_to_image',
    'best_point_to_point_stamped',
    'byte_array',
    'calibration_to_camera_info',
    'camera_info_to_calibration',
    'check_cloud_layout',
    'check_image_layout',
    'check_pair_size',
    'cloud_to_matched_points',
    'decision_to_markers',
    'decision_to_message',
    'disparity_image_message',
    'image_size_problem',
    'image_to_array',
    'matched_points_to_cloud',
    'stamp_to_ns',
    'stereo_matches_colour',
    'stereo_matches_image',
    'stereo_matches_matcher',
    'stereo_matches_message',
    'stereo_pair_to_domain',
    'stereo_pair_with_colour',
    'tf_message_to_transforms',
    'transform_from_message',
    'transform_to_message',
    'transforms_to_tf_message',
]
