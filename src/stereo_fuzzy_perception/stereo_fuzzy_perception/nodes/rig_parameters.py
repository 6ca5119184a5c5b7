"""The stereo rig's pose in world as a parameter group (`rig.*`), for the nodes that need it."""

from __future__ import annotations

from dataclasses import dataclass

from stereo_fuzzy_parameters.spec import parameter

from stereo_fuzzy_perception.core.rig_geometry import StereoRig

_RIG = StereoRig()


@dataclass(frozen=True)
class RigSettings:
    """Pose of the rig (the chapter's alpha, theta, z0 generalised); must match the calibration."""

    baseline_m: float = parameter(
        0.0, 'Distance between the optical centres [m]; 0 = from the calibration (right P); '
        'another value must agree with the calibration within 0.5 mm (fuzzy_best_point_node '
        'refuses it: at start with left|right_calibration_file, else from the first input on)',
        0.0, 2.0, read_only=True)
    alpha_deg: float = parameter(
        _RIG.alpha_deg, 'Rig tilt about its x axis (chapter alpha) [deg]', -90.0, 90.0,
        read_only=True)
    theta_deg: float = parameter(
        _RIG.theta_deg, 'Rig pan about world z (chapter theta) [deg]', -180.0, 180.0,
        read_only=True)
    x0_m: float = parameter(
        _RIG.x0_m, 'x of the optical centres midpoint in world [m]', -10.0, 10.0, read_only=True)
    y0_m: float = parameter(
        _RIG.y0_m, 'y of the optical centres midpoint in world [m]', -10.0, 10.0, read_only=True)
    z0_m: float = parameter(
        _RIG.z0_m, 'Height of the optical centres midpoint (chapter z0) [m]', 0.0, 10.0,
        read_only=True)
    vergence_deg: float = parameter(
        _RIG.vergence_deg, 'Total toe-in between the optical axes [deg]', 0.0, 90.0,
        read_only=True)

    def stereo_rig(self) -> StereoRig:
        """Return the rig these settings describe."""
        return StereoRig(baseline_m=self.baseline_m, alpha_deg=self.alpha_deg,
                         theta_deg=self.theta_deg, x0_m=self.x0_m, y0_m=self.y0_m,
                         z0_m=self.z0_m, vergence_deg=self.vergence_deg)
