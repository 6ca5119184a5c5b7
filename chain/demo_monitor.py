"""Watch the chain from the outside: ground truth, best points, decisions and the gantry.

Used by the demo and the system tests. Objects are keyed by the stamp of their stereo pair: the
simulated bags stamp the images, camera infos and ground truth of one scene alike, and every stage
keeps that stamp, so a best point, its decision and its ground truth meet by stamp.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from geometry_msgs.msg import PointStamped
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from stereo_fuzzy_perception.nodes.topic_names import (
    DISPARITY,
    MATCHES,
    PAIR,
    STEREO_NAMESPACE,
    in_namespace,
)
from stereo_msgs.msg import DisparityImage
from visualization_msgs.msg import Marker

from stereo_fuzzy_msgs.msg import FuzzyDecision, GantryState, StereoMatches, StereoPair

RELIABLE = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
LATCHED_STATE = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                           durability=DurabilityPolicy.TRANSIENT_LOCAL)


def stamp_key(header: object) -> int:
    """Return a header's stamp in nanoseconds, the key that joins one scene's messages."""
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def as_array(point: object) -> np.ndarray:
    """Return a geometry_msgs Point as a numpy vector [m]."""
    return np.array([point.x, point.y, point.z])


@dataclass
class SceneRecord:
    """Everything seen about one scene (one stereo pair)."""

    stamp_ns: int
    ground_truth: np.ndarray | None = None
    best_point: np.ndarray | None = None
    decision: FuzzyDecision | None = None
    pair: StereoPair | None = None
    matches: StereoMatches | None = None
    best_point_order: int = -1
    gantry_index_at_best_point: int = 0
    object_marker: Marker | None = None
    disparity: DisparityImage | None = None


@dataclass
class GantrySample:
    """One gantry state report, as received."""

    index: int
    state: str
    world_position: np.ndarray
    connected: bool
    lines_sent: int
    last_rejection: str


class DemoMonitor:
    """Subscriptions that record what the chain produces, keyed by scene stamp."""

    def __init__(self, node: Node, keep_images: bool = True) -> None:
        self.node = node
        self.scenes: dict[int, SceneRecord] = {}
        self.best_point_order: list[int] = []
        self.gantry: list[GantrySample] = []
        self.latest_gantry_state: GantryState | None = None
        node.create_subscription(PointStamped, 'ground_truth/target', self._on_ground_truth,
                                 RELIABLE)
        node.create_subscription(Marker, 'ground_truth/object', self._on_object, RELIABLE)
        node.create_subscription(PointStamped, 'best_point', self._on_best_point, RELIABLE)
        node.create_subscription(FuzzyDecision, 'best_point/decision', self._on_decision,
                                 RELIABLE)
        node.create_subscription(GantryState, 'gantry/state', self._on_gantry_state,
                                 LATCHED_STATE)
        if keep_images:
            # The chain's camera-rig topics, in the namespace its description puts them in.
            node.create_subscription(StereoPair, in_namespace(STEREO_NAMESPACE, PAIR),
                                     self._on_pair, RELIABLE)
            node.create_subscription(StereoMatches, in_namespace(STEREO_NAMESPACE, MATCHES),
                                     self._on_matches, RELIABLE)
            node.create_subscription(DisparityImage, in_namespace(STEREO_NAMESPACE, DISPARITY),
                                     self._on_disparity, RELIABLE)

    def scene(self, stamp_ns: int) -> SceneRecord:
        """Return the record of the scene with this stamp, creating it if new."""
        return self.scenes.setdefault(stamp_ns, SceneRecord(stamp_ns))

    def _on_ground_truth(self, msg: PointStamped) -> None:
        self.scene(stamp_key(msg.header)).ground_truth = as_array(msg.point)

    def _on_object(self, msg: Marker) -> None:
        self.scene(stamp_key(msg.header)).object_marker = msg

    def _on_best_point(self, msg: PointStamped) -> None:
        record = self.scene(stamp_key(msg.header))
        record.best_point = as_array(msg.point)
        record.gantry_index_at_best_point = len(self.gantry)
        record.best_point_order = len(self.best_point_order)
        self.best_point_order.append(record.stamp_ns)

    def _on_decision(self, msg: FuzzyDecision) -> None:
        self.scene(stamp_key(msg.header)).decision = msg

    def _on_pair(self, msg: StereoPair) -> None:
        self.scene(stamp_key(msg.header)).pair = msg

    def _on_matches(self, msg: StereoMatches) -> None:
        self.scene(stamp_key(msg.header)).matches = msg

    def _on_disparity(self, msg: DisparityImage) -> None:
        self.scene(stamp_key(msg.header)).disparity = msg

    def gantry_path(self, until: int | None = None) -> np.ndarray:
        """Return the gantry's reported world positions [m] (N x 3), up to report `until`."""
        samples = self.gantry if until is None else self.gantry[:until + 1]
        positions = [s.world_position for s in samples if s.connected]
        return np.array(positions) if positions else np.zeros((0, 3))

    def _on_gantry_state(self, msg: GantryState) -> None:
        self.latest_gantry_state = msg
        self.gantry.append(GantrySample(len(self.gantry), msg.state,
                                        as_array(msg.world_position), msg.connected,
                                        int(msg.lines_sent), msg.last_rejection))

    def gantry_ready(self) -> bool:
        """Return True once the driver reports a connected controller that accepts motion."""
        state = self.latest_gantry_state
        return bool(state and state.connected and not state.homing_required
                    and state.state == GantryState.STATE_IDLE)

    def idle_at(self, position: np.ndarray, tolerance_m: float,
                since: int = 0) -> GantrySample | None:
        """Return the first Idle report within `tolerance_m` of `position` at or after report
        number `since`, if any."""
        for sample in self.gantry[since:]:
            if (sample.state == GantryState.STATE_IDLE
                    and np.linalg.norm(sample.world_position - position) <= tolerance_m):
                return sample
        return None

    def driver_summary(self, record: SceneRecord) -> str:
        """Say what the driver reported after this scene's best point: lines sent, states,
        and a refusal if there was one (why a move did not happen)."""
        since = record.gantry_index_at_best_point
        before = self.gantry[since - 1] if since > 0 else None
        after = self.gantry[since:]
        if not after:
            return 'no gantry/state report after the best point'
        sent = after[-1].lines_sent - (before.lines_sent if before else 0)
        states = sorted({sample.state for sample in after})
        rejection = after[-1].last_rejection
        refused = (f'; last refusal: {rejection}'
                   if rejection and (before is None or rejection != before.last_rejection)
                   else '')
        return f'{sent} lines sent since, states {"/".join(states)}{refused}'
