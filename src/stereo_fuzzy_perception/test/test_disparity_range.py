"""The disparity search range derived from the calibration, the rig pose and the workspace."""

import numpy as np
import pytest
from grid_scenes import Box, grid_matches
from stereo_fuzzy_perception.core.camera_model import StereoCalibration
from stereo_fuzzy_perception.core.matching.disparity_range import (
    DisparityRangeError,
    workspace_disparity_range,
)
from stereo_fuzzy_perception.core.rig_geometry import StereoRig
from stereo_fuzzy_perception.simulation.synthetic_scenes import (
    default_camera_matrix,
    rectified_calibration,
)

WORKSPACE = ((0.0, 0.0, 0.0), (0.4, 0.3, 0.2))
RIGS = [StereoRig(),
        StereoRig(baseline_m=0.10, alpha_deg=30.0, z0_m=0.7, y0_m=-0.3, vergence_deg=8.0),
        StereoRig(baseline_m=0.045, alpha_deg=20.0, theta_deg=12.0, x0_m=0.24, y0_m=-0.1,
                  z0_m=0.33, vergence_deg=3.0),
        StereoRig(baseline_m=0.08, alpha_deg=0.0, x0_m=0.2, y0_m=0.15, z0_m=0.75,
                  vergence_deg=0.0)]


@pytest.mark.parametrize('rig', RIGS)
def test_the_range_holds_the_surface_and_the_tallest_object(rig):
    left, right = rectified_calibration(rig, default_camera_matrix())
    derived = workspace_disparity_range(StereoCalibration(left, right),
                                        rig.world_from_left_camera(), *WORKSPACE)
    for box in (None, Box((0.2, 0.15), 0.04, 0.2)):
        points, _, _ = grid_matches(rig, box, 0.0, 4)
        world = points.xyz @ rig.world_from_left_camera()[:3, :3].T + \
            rig.world_from_left_camera()[:3, 3]
        in_box = np.all((world >= (-0.05, -0.05, -0.01)) & (world <= (0.45, 0.35, 0.21)),
                        axis=1)
        disparity = (points.u_left - points.u_right)[in_box]
        assert disparity.min() >= derived.min_disparity
        assert disparity.max() <= derived.max_disparity
    assert derived.disparity_range <= 512


def test_a_rig_looking_away_from_the_workspace_is_refused():
    rig = StereoRig(x0_m=5.0)  # 5 m to the side
    left, right = rectified_calibration(rig, default_camera_matrix())
    with pytest.raises(DisparityRangeError, match='workspace box'):
        workspace_disparity_range(StereoCalibration(left, right),
                                  rig.world_from_left_camera(), *WORKSPACE)
