"""Choose the best point of a set of matched points: the fuzzy system and its baselines. ROS-free.

The public entry point for nodes, the demo and benchmarks:

    chooser = BestPointChooser.create('fuzzy_fitted', AreaConfig(), StereoRig())
    decision = chooser.decide(points, left_calibration, right_calibration)

Every selector shares steps 1-3 (correlation_area.py, four_areas.py) and the height rule of
step 6: the best point's z is the top height (median height of the correlation area) plus the
selector's learned height offset (fitted rule base, neural network; zero otherwise). Selectors
differ in x, y:

- fuzzy_fitted / fuzzy_chapter: Eq. 10 over the rule base's twelve rules (fuzzy_inference.py).
- centroid: the mean of the correlation area's points.
- max_score: the correlation-area match with the highest correlation score (the matches' own
  area: an outline from the image has no scores of its own).
- neural_network: the MLP baseline's offset from the centroid (neural_baseline.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from stereo_fuzzy_perception.core.best_point.colour_silhouette import colour_top
from stereo_fuzzy_perception.core.best_point.correlation_area import (
    ASSUMED_SURFACE,
    DEGENERATE_AREA,
    LOOK_COLOUR_SILHOUETTE,
    LOOK_FACE_AT_MODE,
    LOOK_FITTED_PIECES,
    LOOK_FITTED_SMALL_FACE,
    LOOK_MATCHES,
    LOOK_PIECES_OUTLINED,
    LOOK_PLAIN_FACE,
    LOOK_PLAIN_OBJECT,
    LOOK_PLAIN_TOP_AT_MATCHED_HEIGHT,
    LOOK_TEXTURED_REGION,
    MIN_OBJECT_AREA_PX,
    NO_OBJECT,
    NO_POINTS,
    NO_RULE_FIRED,
    STATUS_OK,
    TOO_FEW_POINTS,
    UNCERTAIN_TOP,
    AreaConfig,
    CorrelationArea,
    find_correlation_area,
    find_textured_area,
)
from stereo_fuzzy_perception.core.best_point.face_appearance import low_face_from_appearance
from stereo_fuzzy_perception.core.best_point.face_outline import (
    face_from_image,
    plain_face_from_image,
)
from stereo_fuzzy_perception.core.best_point.four_areas import FourAreas, split_into_areas
from stereo_fuzzy_perception.core.best_point.fuzzy_inference import infer
from stereo_fuzzy_perception.core.best_point.neural_baseline import (
    NeuralBaseline,
    NeuralBaselineError,
    neural_base_point,
    neural_features,
)
from stereo_fuzzy_perception.core.best_point.object_segmentation import (
    grid_step,
    hull_fill,
    image_regions,
    on_pixel_grid,
    width_m,
)
from stereo_fuzzy_perception.core.best_point.plain_object import (
    plain_face_without_side_wall,
    plain_object_from_image,
    plain_top_at_matched_height,
)
from stereo_fuzzy_perception.core.best_point.rule_base import (
    RuleBase,
    RuleBaseError,
    data_path,
    load_rule_base,
    packaged_rule_base,
)
from stereo_fuzzy_perception.core.best_point.surface_lookalike import (
    MAX_OVERLAP as SURFACE_LOOKALIKE_OVERLAP,
)
from stereo_fuzzy_perception.core.best_point.surface_lookalike import looks_like_the_surface
from stereo_fuzzy_perception.core.best_point.top_shape_fit import (
    TopShapeMemory,
    centre_for_refused_face,
    fitted_around,
    point_with_fitted_top,
)
from stereo_fuzzy_perception.core.best_point.work_surface import SurfacePlane
from stereo_fuzzy_perception.core.camera_model import CameraCalibration
from stereo_fuzzy_perception.core.matched_points import MatchedPoints, RectifiedImage
from stereo_fuzzy_perception.core.rig_geometry import StereoRig

NON_FINITE_POINT = 'non_finite_point'
"""Status of a decision whose point came out NaN or infinite (e.g. overflowing weights)."""
OUTSIDE_WORKSPACE = 'outside_workspace'
"""Status of a decision whose point lies outside the workspace box: never published."""
OUTPUT_STATUSES = (NON_FINITE_POINT, OUTSIDE_WORKSPACE)
"""Refusals of the final output check, in the order it applies them."""

SELECTORS = ('fuzzy_fitted', 'fuzzy_chapter', 'centroid', 'max_score', 'neural_network')
FUZZY_SELECTORS = ('fuzzy_fitted', 'fuzzy_chapter')
NEURAL_WEIGHTS_FILE = 'neural_baseline.npz'

PIECES_OUTLINED_FILL_SHARE = 0.8
"""A face in pieces (its matches fill less than min_top_fill of their hull) that the image does
not show as one plain region is outlined from the image's edges like a whole face when its
fill is at least this share of min_top_fill: a textured top matched in blotches (wood grain, a
print) is in pieces only just, and its rim is in the image. Faces further in pieces are more
often bits of side wall and table; where that starts, measured, is in the package README
(step 1, "A textured top just in pieces")."""
PIECES_OUTLINED_MIN_POINTS = 2
"""...when it holds at least this many times min_points matches: a few dozen matches at a
coarse point stride say too little about where the rim is..."""
PIECES_OUTLINED_ONE_PIECE = 0.8
"""...and when at least this share of its matches is one connected piece (a face with holes):
the outline is drawn around the largest piece (face_outline.py), so separate stripes would
give the centre of one of them (test_face_outline.py builds such a top; the splits have none)."""


class SelectorError(ValueError):
    """A selector that cannot be built (unknown name, bad rule base or weights file)."""


def _nan_points(count: int) -> np.ndarray:
    return np.full((count, 3), math.nan)


def _nan_values(count: int) -> np.ndarray:
    return np.full(count, math.nan)


@dataclass
class BestPointDecision:
    """Everything FuzzyDecision reports about one set of matched points.

    Arrays indexed by area hold areas 1..4 at 0..3; rule arrays follow the rule base order.
    NaN marks a value that could not be computed (the status says why).

    Attributes:
        selector: The selector's name.
        rule_base: Name of the rule base ('' for non-fuzzy selectors).
        status: STATUS_OK or a status code (correlation_area.py).
        reason: Human-readable reason when no point was chosen.
        best_point_world: (3,) [m] in `world`, or None.
        best_point_camera: (3,) [m] in the camera frame of the input, or None.
        points_in: Matches received.
        points_valid: Finite, in the workspace box, above the surface.
        clusters_found: Separated clusters among the valid points.
        points_used: Points of the correlation area.
        top_height: World z of the object's top [m].
        border_points: (4, 3) [m] world: min u, max u, min v, max v.
        border_distances: (6,) Eq. 9 distances [m].
        area_centres: (4, 3) [m] world.
        area_centres_u_left: (4,) [px].
        area_centres_v_left: (4,) [px].
        area_centres_u_right: (4,) [px].
        area_point_counts: (4,).
        d1: (4,) [px].
        d2: (4,) [px].
        ratio: (4,).
        rule_names: Rule names in rule base order.
        membership_degrees: (L,).
        firing_strengths: (L,).
        eq10_point: (3,) Eq. 10 point before the height rule [m], or None.
        consequent_points: (L, 3) the rules' y_l [m].
        area_points_world: (M, 3) the correlation area's points in `world` [m] (for markers).
        surface: The work surface measured from the points, and their disparity noise.
        object_height_sigmas: Median height of the object's region in sigmas of its noise.
        look: Which look at the pair gave the face (correlation_area.LOOK_*).
    """

    selector: str
    rule_base: str = ''
    status: str = STATUS_OK
    reason: str = ''
    best_point_world: np.ndarray | None = None
    best_point_camera: np.ndarray | None = None
    points_in: int = 0
    points_valid: int = 0
    clusters_found: int = 0
    points_used: int = 0
    top_height: float = math.nan
    border_points: np.ndarray = field(default_factory=lambda: _nan_points(4))
    border_distances: np.ndarray = field(default_factory=lambda: _nan_values(6))
    area_centres: np.ndarray = field(default_factory=lambda: _nan_points(4))
    area_centres_u_left: np.ndarray = field(default_factory=lambda: _nan_values(4))
    area_centres_v_left: np.ndarray = field(default_factory=lambda: _nan_values(4))
    area_centres_u_right: np.ndarray = field(default_factory=lambda: _nan_values(4))
    area_point_counts: np.ndarray = field(default_factory=lambda: np.zeros(4, dtype=np.int64))
    d1: np.ndarray = field(default_factory=lambda: _nan_values(4))
    d2: np.ndarray = field(default_factory=lambda: _nan_values(4))
    ratio: np.ndarray = field(default_factory=lambda: _nan_values(4))
    rule_names: list[str] = field(default_factory=list)
    membership_degrees: np.ndarray = field(default_factory=lambda: np.zeros(0))
    firing_strengths: np.ndarray = field(default_factory=lambda: np.zeros(0))
    eq10_point: np.ndarray | None = None
    consequent_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    area_points_world: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    surface: SurfacePlane = ASSUMED_SURFACE
    object_height_sigmas: float = math.nan
    look: str = LOOK_MATCHES

    @property
    def has_best_point(self) -> bool:
        """Return True when a best point was chosen."""
        return self.best_point_world is not None

    def status_text(self) -> str:
        """Return 'ok' or 'code: reason' (the FuzzyDecision status field)."""
        return STATUS_OK if self.status == STATUS_OK else f'{self.status}: {self.reason}'


def principal_point(calibration: CameraCalibration) -> tuple[float, float]:
    """Return (cx, cy) [px] of a rectified projection matrix P."""
    return float(calibration.P[0, 2]), float(calibration.P[1, 2])


def disparity_shift(left: CameraCalibration, right: CameraCalibration) -> float:
    """Return cx_left - cx_right of the rectified projections [px] (disparity at infinity)."""
    return float(left.P[0, 2] - right.P[0, 2])


@dataclass
class BestPointChooser:
    """One selector with its configuration, ready to decide on sets of matched points.

    Attributes:
        selector: One of SELECTORS.
        area_config: How the correlation area is found.
        world_from_camera: 4x4 pose of the matched points' frame (left optical) in `world`.
        rule_base: The fuzzy selectors' rule base (None otherwise).
        network: The neural_network selector's weights (None otherwise).
        top_shape_memory: Where the fitted top of the last object seen is kept for the pairs
            of the same object that follow (a node's; None: every decision fits its own).
    """

    selector: str
    area_config: AreaConfig
    world_from_camera: np.ndarray
    rule_base: RuleBase | None = None
    network: NeuralBaseline | None = None
    top_shape_memory: TopShapeMemory | None = field(default=None, compare=False)

    @classmethod
    def create(cls, selector: str, area_config: AreaConfig, rig: StereoRig,
               rule_base_file: str = '', weights_file: str = '') -> BestPointChooser:
        """Build a selector, loading its rule base or weights (packaged ones by default).

        Args:
            selector: One of SELECTORS.
            area_config: How the correlation area is found.
            rig: The stereo rig; the left camera's pose maps points to `world`.
            rule_base_file: Rule base for a fuzzy selector; '' for the packaged one.
            weights_file: Network weights for neural_network; '' for the packaged ones.

        Raises:
            SelectorError: Unknown selector, or a file that cannot be used (reason included).
        """
        if selector not in SELECTORS:
            raise SelectorError(f'selector {selector!r} is not one of {", ".join(SELECTORS)}')
        reason = area_config.problem()
        if reason:
            raise SelectorError(reason)
        rule_base = network = None
        try:
            if selector in FUZZY_SELECTORS:
                rule_base = (load_rule_base(rule_base_file) if rule_base_file
                             else packaged_rule_base(selector))
            elif selector == 'neural_network':
                network = NeuralBaseline.load(
                    Path(weights_file) if weights_file else data_path(NEURAL_WEIGHTS_FILE))
        except (RuleBaseError, NeuralBaselineError) as error:
            raise SelectorError(str(error)) from error
        return cls(selector, area_config, rig.world_from_left_camera(), rule_base, network)

    def decide(self, points: MatchedPoints, left: CameraCalibration,
               right: CameraCalibration) -> BestPointDecision:
        """Choose the best point of one set of matched points (steps 1-6).

        Args:
            points: Matched points in the left camera optical frame.
            left: Rectified calibration of the left image (P gives the principal point).
            right: Rectified calibration of the right image.

        Returns:
            The decision; when no point can be chosen, status and reason say why. Bad points
            (NaN, infinite, outside the workspace) are ignored, never raised on.
        """
        decision = BestPointDecision(self.selector,
                                     self.rule_base.name if self.rule_base else '')
        if self.rule_base is not None:
            decision.rule_names = [rule.name for rule in self.rule_base.rules]
        config = self.area_config
        if self.selector == 'max_score':
            # Scores belong to matches: an area outlined from the image has one score for all.
            config = replace(config, outline_from_image=False)
        area = decision_area(points, left, right, self.world_from_camera, config)
        decision.surface = area.surface
        decision.object_height_sigmas = area.object_height_sigmas
        decision.points_in, decision.points_valid = area.points_in, area.points_valid
        decision.clusters_found, decision.points_used = area.clusters_found, area.points_used
        decision.top_height = area.top_height
        decision.area_points_world = area.xyz_world
        decision.look = area.look
        if config.colour_silhouette and points.left_colour is not None and (
                self.selector != 'max_score'):
            found = self._decide_on_colour(decision, area, points, left, right)
            if found is not None:
                return found
        if not area.ok:
            return (self._decide_on_fitted_face(decision, area, points, left, right)
                    or self._refuse(decision, area.status, area.reason))
        return self._decide_on(decision, area, points, left, right)

    def _decide_on(self, decision: BestPointDecision, area: CorrelationArea,
                   points: MatchedPoints, left: CameraCalibration, right: CameraCalibration,
                   fit_top_shape: bool = True) -> BestPointDecision:
        """Choose the point of an accepted face (steps 2-6), moved toward the top fitted around
        it when fit_top_shape (and the area config's) allow."""
        config = self.area_config
        areas = split_into_areas(area, principal_point(left), principal_point(right))
        self._record_areas(decision, areas)
        if self.selector == 'centroid':
            horizontal = areas.centre
            height_offset = 0.0
        elif self.selector == 'max_score':
            best = np.flatnonzero(area.score == area.score.max())
            if len(best) > 1:  # ties: the smallest (x, y, z), so input order cannot matter
                world = area.xyz_world[best]
                best = best[np.lexsort((world[:, 2], world[:, 1], world[:, 0]))]
            horizontal = area.xyz_world[best[0]]
            height_offset = 0.0
        else:
            if not areas.ok:
                return self._refuse(decision, areas.status, areas.reason)
            if self.network is not None:
                offset = self.network.predict(neural_features(area, areas))
                point = neural_base_point(area, areas) + offset
                return self._choose(decision, point)
            assert self.rule_base is not None
            result = infer(self.rule_base, areas)
            decision.membership_degrees = result.membership_degrees
            decision.firing_strengths = result.firing_strengths
            decision.consequent_points = result.consequent_points
            if result.point is None:
                empty = [str(k + 1) for k in range(4) if areas.counts[k] == 0]
                return self._refuse(decision, NO_RULE_FIRED, (
                    'no rule fired: ratios ' + ', '.join(f'{r:.3g}' for r in areas.ratio)
                    + ' lie outside every membership function'
                    + (f' or their areas ({", ".join(empty)}) are empty' if empty else '')))
            decision.eq10_point = result.point
            horizontal = result.point
            height_offset = self.rule_base.height_offset_m
        point = np.array([horizontal[0], horizontal[1], area.top_height + height_offset])
        if fit_top_shape and config.fit_top_shape and self.selector != 'max_score':
            point = point_with_fitted_top(area, points, left, right, self.world_from_camera,
                                          point, self.top_shape_memory)
        return self._choose(decision, point)

    def _decide_on_fitted_face(self, decision: BestPointDecision, area: CorrelationArea,
                               points: MatchedPoints, left: CameraCalibration,
                               right: CameraCalibration) -> BestPointDecision | None:
        """Return a decision at the centre of the top fitted around a face refused after every
        look as in pieces, or as smaller in the image than any object's top
        (top_shape_fit.centre_for_refused_face), or None (the refusal stands). The selector's
        point on the refused face is where the fit starts; a face whose matches are sparse,
        or a narrow top's few, is still matched at its top's height, and the fit finds its
        outline in both images (why, measured: the package README, "A face in pieces given
        its fitted top" and "A face too small in the image given its fitted top")."""
        if area.status == UNCERTAIN_TOP and area.face_in_pieces is not None:
            face, look, count = area.face_in_pieces, LOOK_FITTED_PIECES, 'pieces'
        elif area.status == NO_OBJECT and area.face_too_small is not None:
            face, look, count = area.face_too_small, LOOK_FITTED_SMALL_FACE, 'small'
        else:
            return None
        if not face.ok or not self.area_config.fit_top_shape or self.selector == 'max_score':
            return None
        started = self._decide_on(replace(decision), face, points, left, right,
                                  fit_top_shape=False)
        if started.best_point_world is None:
            return None
        fit = fitted_around(face, points, left, right, self.world_from_camera,
                            started.best_point_world, self.top_shape_memory)
        point = centre_for_refused_face(started.best_point_world, fit)
        if point is None:
            return None
        if self.top_shape_memory is not None:
            self.top_shape_memory.counts[count] += 1
        # the fitted centre is given only if _choose passes it
        started.best_point_world = started.best_point_camera = None
        started.top_height = face.top_height
        started.area_points_world = face.xyz_world
        started.look = look
        return self._choose(started, point)

    def _decide_on_colour(self, decision: BestPointDecision, area: CorrelationArea,
                          points: MatchedPoints, left: CameraCalibration,
                          right: CameraCalibration) -> BestPointDecision | None:
        """Return a decision at the centre of the top the colour silhouette shows
        (colour_silhouette.py), or None (no silhouette, or a top not measured: the grey looks
        decide). Its height, like every look's, is its height above the measured surface."""
        config = self.area_config
        top, _ = colour_top(points, left, right, self.world_from_camera, area.surface,
                            (config.workspace_min, config.workspace_max),
                            config.max_object_across_m, config.max_object_height_m)
        if top is None or not config.min_object_height_m <= top.top_height <= (
                config.max_object_height_m):
            return None
        colour = replace(decision, look=LOOK_COLOUR_SILHOUETTE, top_height=top.top_height,
                         points_used=top.top_matches, area_points_world=top.footprint)
        return self._choose(colour, np.array([top.point[0], top.point[1], top.top_height]))

    def _choose(self, decision: BestPointDecision, point: np.ndarray) -> BestPointDecision:
        """Accept `point` as the best point only if it passes output_problem."""
        point = np.asarray(point, dtype=float)
        problem = output_problem(point, self.area_config)
        if problem is not None:
            return self._refuse(decision, *problem)
        decision.best_point_world = point
        pose = self.world_from_camera
        decision.best_point_camera = pose[:3, :3].T @ (decision.best_point_world - pose[:3, 3])
        return decision

    @staticmethod
    def _refuse(decision: BestPointDecision, status: str, reason: str) -> BestPointDecision:
        decision.status, decision.reason = status, reason
        return decision

    @staticmethod
    def _record_areas(decision: BestPointDecision, areas: FourAreas) -> None:
        decision.border_points = areas.border_points
        decision.border_distances = areas.border_distances
        decision.area_centres = areas.centres
        decision.area_centres_u_left = areas.centres_u_left
        decision.area_centres_v_left = areas.centres_v_left
        decision.area_centres_u_right = areas.centres_u_right
        decision.area_point_counts = areas.counts
        decision.d1, decision.d2, decision.ratio = areas.d1, areas.d2, areas.ratio


def output_problem(point: np.ndarray, config: AreaConfig) -> tuple[str, str] | None:
    """Return (status, reason) when `point` [m, world] must not be published, else None.

    The last check before a best point leaves the chooser, whatever the selector, rule base or
    weights: the point must be three finite numbers inside the workspace box of `config`
    (where the gantry can go and where the correlation area's points were taken from).
    """
    if point.shape != (3,) or not np.all(np.isfinite(point)):
        return NON_FINITE_POINT, f'the selector gave a non-finite point {_describe(point)}'
    low, high = np.asarray(config.workspace_min), np.asarray(config.workspace_max)
    outside = [f'{axis} = {value:.4g} not in [{lo:g}, {hi:g}]'
               for axis, value, lo, hi in zip('xyz', point, low, high, strict=True)
               if not lo <= value <= hi]
    if outside:
        return OUTSIDE_WORKSPACE, ("the selector's point lies outside the workspace box: "
                                   + ', '.join(outside))
    return None


def _describe(point: np.ndarray) -> str:
    return '(' + ', '.join(f'{value:.4g}' for value in np.ravel(point)[:3]) + ')'


def load_selector_files(rule_base_file: str, weights_file: str) -> None:
    """Load and check the given rule base and weights files, whichever selector is active.

    A file set while another selector is active is checked now, not when the selector is
    switched to it. Empty names (the packaged files) are not read.

    Raises:
        SelectorError: With the reason of the first file that cannot be used.
    """
    try:
        if rule_base_file:
            load_rule_base(rule_base_file)
        if weights_file:
            NeuralBaseline.load(weights_file)
    except (RuleBaseError, NeuralBaselineError) as error:
        raise SelectorError(str(error)) from error


FACE_TOO_THIN = (TOO_FEW_POINTS, UNCERTAIN_TOP)
"""Refusals of a face found but too thin to measure: at a point stride above 1 the pair is
looked at again at stride 1 (second_look.py) before its texture is."""


def decision_area(points: MatchedPoints, left: CameraCalibration, right: CameraCalibration,
                  world_from_camera: np.ndarray, config: AreaConfig) -> CorrelationArea:
    """Return step 1 as every selector sees it: the correlation area, its outline taken from
    the image when the matches bring it (face_outline.py), or why there is none.

    Training (area_features) goes through here too, so the fitted selectors learn on the
    areas they will be given. A face narrower than any object (min_object_across_m) or
    covering less of the image than any object (MIN_OBJECT_AREA_PX) is refused whichever way
    its outline came (the latter keeps its face, CorrelationArea.face_too_small, for the top
    fitted around it). A pair refused after every look at its face is looked at once more as
    the image's textured regions (correlation_area.find_textured_area), and then, with the
    right image, for one plain object on a textured surface (plain_object.py). A face that
    passed it all and stands low has its rim refined from its appearance (face_appearance.py).
    A face refused for its scatter, and a sliver, may be a plain top's: the plain region of
    the image that holds it is taken at its height when both images put it there
    (plain_object.plain_top_at_matched_height). A face taken whole from the image's plain
    region loses a side wall of its grey that joined it, and one that is mostly wall is no
    face (plain_face_without_side_wall). Last, a face standing barely out of the surface
    that looks like the surface around it is no object (surface_lookalike.py).
    """
    shift = disparity_shift(left, right)
    area = find_correlation_area(points, world_from_camera, config, shift)
    scattered, pieces = area.scattered_face, area.face_in_pieces
    if points.left_image is not None and config.outline_from_image:
        if area.ok:
            area = face_from_image(area, points.left_image, left, right, world_from_camera,
                                   config.min_points) or area
        elif pieces is not None:
            # a face in pieces keeps its matches' height: the rim's matches that are there
            # lie on the top
            area = (_plain_face(plain_face_from_image(
                        pieces, points.left_image, left, right, world_from_camera,
                        config.min_points, config.max_object_across_m), points, left, right,
                        world_from_camera, config)
                    or _looked(LOOK_FACE_AT_MODE, _face_at_mode(
                        area, points.left_image, left, right, world_from_camera,
                        config.min_points))
                    or _looked(LOOK_PIECES_OUTLINED, _outlined_pieces(
                        pieces, points.left_image, left, right, world_from_camera, config))
                    or area)
        elif area.scattered_face is not None and points.right_image is not None:
            # a scattered face's matched heights are not its top's: the height must come from
            # where the plain region lies in both images
            area = _plain_face(plain_face_from_image(
                area.scattered_face, points.left_image, left, right, world_from_camera,
                config.min_points, config.max_object_across_m, points.right_image,
                config.max_object_height_m), points, left, right, world_from_camera,
                config) or area
        if not area.ok and area.status != NO_POINTS and not area.texture_tried and (
                area.status not in FACE_TOO_THIN or _matches_step(points) <= 1):
            # A textured object on a plain or sparsely marked table can be found with the
            # table's mismatches around it, and refused for them.
            textured = find_textured_area(points, world_from_camera, config, shift)
            if textured is not None:
                area = replace(face_from_image(textured, points.left_image, left, right,
                                               world_from_camera, config.min_points)
                               or textured, look=LOOK_TEXTURED_REGION)
        if not area.ok and points.right_image is not None:
            # A plain top on a textured surface is matched only along its rim, and a low one
            # stands out of nothing; the image still shows it, both images its height.
            area = _looked(LOOK_PLAIN_OBJECT, plain_object_from_image(
                area, points, left, right, world_from_camera, config)) or area
        if not area.ok and scattered is not None and points.right_image is not None:
            # Last, a scattered face whose top is plain: the plain region holding it, at its
            # matched height when both images put the region's rim there.
            area = _looked(LOOK_PLAIN_TOP_AT_MATCHED_HEIGHT, plain_top_at_matched_height(
                scattered, points, left, right, world_from_camera, config)) or area
    if not area.ok and area.status == UNCERTAIN_TOP and pieces is not None:
        # the matches' face in pieces, for the top fitted around it (BestPointChooser.decide)
        area = replace(area, face_in_pieces=pieces)
    if area.ok and config.min_object_across_m > 0.0:
        width = width_m(area.xyz_world[:, :2])
        if (width < config.min_object_across_m and config.outline_from_image
                and points.right_image is not None):
            # A plain top whose matches are one arc of its rim: the plain region the arc
            # bounds, at the arc's height when both images put the region there.
            whole = _looked(LOOK_PLAIN_TOP_AT_MATCHED_HEIGHT, plain_top_at_matched_height(
                area, points, left, right, world_from_camera, config))
            if whole is not None:
                area, width = whole, width_m(whole.xyz_world[:, :2])
        if width < config.min_object_across_m:
            return replace(area, status=NO_OBJECT, reason=(
                f'the top face found is {1000.0 * width:.1f} mm wide on the work surface, '
                f'narrower than any object (min_object_across_m={config.min_object_across_m:g})'
                ": a sliver of a face, whose centre is not the face's"))
    too_small = ''  # why a face is too small in the image to be taken on its matches alone
    if area.ok and on_pixel_grid(area.u_left) and on_pixel_grid(area.v_left):
        # counted on the matches' pixel grid (correlation_node's); points from elsewhere
        # (geometric scenes) have no grid to count an image area on
        step = grid_step(area.u_left, area.v_left)
        covered = len(area.u_left) * step ** 2
        if covered < MIN_OBJECT_AREA_PX:
            # On a bare textured table a blob of mismatches the size of a correlation window
            # or two can stand out in sigmas; no object's top is that small in the image.
            too_small = (f'the top face found covers {covered:.0f} px of the left image, less '
                         f"than any object's top ({MIN_OBJECT_AREA_PX:g} px): a blob of "
                         'mismatches, not a face')
    if area.ok and points.left_image is not None and config.outline_from_image:
        # Only a face that passed the tests above: its appearance refines where its rim
        # lies, it does not make a sliver a face (nor a blob one: that stays refused).
        area = low_face_from_appearance(area, points.left_image, left, right,
                                        world_from_camera, config.min_points) or area
    if area.ok and points.left_image is not None and config.outline_from_image:
        # A patch of a repeating table matched a repeat off stands barely out, as a low top
        # does; unlike a top it looks like the table around it.
        overlap = looks_like_the_surface(area.u_left, area.v_left, area.object_height_sigmas,
                                         points.left_image)
        if overlap is not None:
            return replace(area, status=NO_OBJECT, reason=too_small or (
                f'the top face found stands only {area.object_height_sigmas:.1f} sigmas out of '
                f'the work surface and looks like the surface around it (appearance overlap '
                f'{overlap:.2f} > {SURFACE_LOOKALIKE_OVERLAP:g}): a patch of the surface '
                'matched a repeat of its texture away, not an object'))
    if area.ok and too_small:
        # A narrow box's top can be that small too: BestPointChooser fits the top around
        # it, and only a clear fit found again gives it a point.
        return replace(area, status=NO_OBJECT, reason=too_small, face_too_small=area)
    return area


def _plain_face(found: CorrelationArea | None, points: MatchedPoints,
                left: CameraCalibration, right: CameraCalibration,
                world_from_camera: np.ndarray, config: AreaConfig) -> CorrelationArea | None:
    """Return a face taken whole from the image's plain region (LOOK_PLAIN_FACE), without
    a side wall of its grey where one joined it (plain_face_without_side_wall), or None (no
    plain region, or one that is mostly wall)."""
    if found is None:
        return None
    return _looked(LOOK_PLAIN_FACE, plain_face_without_side_wall(
        found, points, left, right, world_from_camera, config))


def _looked(look: str, area: CorrelationArea | None) -> CorrelationArea | None:
    """Return the area a look at the pair gave, marked with that look (LOOK_*), or None."""
    return None if area is None else replace(area, look=look)


def _face_at_mode(area: CorrelationArea, image: RectifiedImage, left: CameraCalibration,
                  right: CameraCalibration, world_from_camera: np.ndarray, min_points: int
                  ) -> CorrelationArea | None:
    """Return a face in pieces taken at the mode of its heights (CorrelationArea.face_at_mode),
    outlined from the image where it can be, or None when there is none."""
    if area.face_at_mode is None:
        return None
    return face_from_image(area.face_at_mode, image, left, right, world_from_camera,
                           min_points) or area.face_at_mode


def _matches_step(points: MatchedPoints) -> float:
    """Return the grid spacing of the finite matches [px]: a NaN row a peer sent would make
    any grid look like a stride of 1."""
    finite = np.isfinite(points.u_left) & np.isfinite(points.v_left)
    return grid_step(points.u_left[finite], points.v_left[finite])


def _outlined_pieces(pieces: CorrelationArea, image: RectifiedImage, left: CameraCalibration,
                     right: CameraCalibration, world_from_camera: np.ndarray,
                     config: AreaConfig) -> CorrelationArea | None:
    """Return a face in pieces outlined from the left image like a whole face, or None when it
    is too much in pieces, too sparse or in separate pieces (PIECES_OUTLINED_*), or when the
    image gives no outline."""
    u, v = pieces.u_left, pieces.v_left
    step = grid_step(u, v)
    if (pieces.points_used < PIECES_OUTLINED_MIN_POINTS * config.min_points
            or hull_fill(u, v, step) < PIECES_OUTLINED_FILL_SHARE * config.min_top_fill):
        return None
    labels, _ = image_regions(u, v, np.ones(len(u), dtype=bool), step)
    if np.bincount(labels)[1:].max() < PIECES_OUTLINED_ONE_PIECE * len(u):
        return None
    return face_from_image(pieces, image, left, right, world_from_camera, config.min_points)


def area_features(points: MatchedPoints, left: CameraCalibration, right: CameraCalibration,
                  world_from_camera: np.ndarray, config: AreaConfig
                  ) -> tuple[CorrelationArea, FourAreas | None]:
    """Return steps 1-3 for one scene (for training): the area and its four areas, if any."""
    area = decision_area(points, left, right, world_from_camera, config)
    if not area.ok:
        return area, None
    areas = split_into_areas(area, principal_point(left), principal_point(right))
    return area, (areas if areas.status == STATUS_OK else None)


__all__ = ['DEGENERATE_AREA', 'NON_FINITE_POINT', 'OUTPUT_STATUSES', 'OUTSIDE_WORKSPACE',
           'SELECTORS', 'BestPointChooser', 'BestPointDecision', 'SelectorError',
           'area_features', 'decision_area', 'disparity_shift', 'load_selector_files',
           'output_problem', 'principal_point']
