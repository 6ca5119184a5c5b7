"""The perception nodes' QoS profiles by name: the shared ones and the camera input.

The profiles the gantry driver uses too (results, diagnostics, /tf, /tf_static) are defined
once in stereo_fuzzy_parameters.qos and re-exported here, so a node imports one module. Only
the perception nodes read cameras: camera inputs take the sensor-data profile (best effort,
keep last 5), as camera drivers publish them, with the reliability overridable by parameter.
"""

from rclpy.qos import ReliabilityPolicy, qos_profile_sensor_data
from stereo_fuzzy_parameters.qos import (
    DIAGNOSTICS,
    RESULTS,
    TF,
    TF_STATIC,
    TF_STATIC_BROADCAST,
)

__all__ = ['CAMERA_INPUT', 'DIAGNOSTICS', 'RESULTS', 'TF', 'TF_STATIC', 'TF_STATIC_BROADCAST',
           'reliability_from_name']

CAMERA_INPUT = qos_profile_sensor_data


def reliability_from_name(name: str) -> ReliabilityPolicy:
    """Map a parameter value ('reliable' or 'best_effort') to a ReliabilityPolicy."""
    return {'reliable': ReliabilityPolicy.RELIABLE,
            'best_effort': ReliabilityPolicy.BEST_EFFORT}[name]
