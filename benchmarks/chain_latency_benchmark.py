"""End-to-end latency of the perception chain through DDS, with the nodes as separate processes.

    source scripts/env.sh
    python benchmarks/chain_latency_benchmark.py                      # 15 and 30 Hz, 20 s each
    python benchmarks/chain_latency_benchmark.py --rates 15 --duration 60
    python benchmarks/chain_latency_benchmark.py --rates 30 --pairs-per-scene 30 --no-tracking

Starts stereo_sync_node, correlation_node and fuzzy_best_point_node as processes (as `ros2
launch` would; parameters from chain/demo_params.yaml) in a ROS domain of their own with
localhost-only discovery. A publisher node of this process, on its own executor and thread,
publishes pre-encoded 640x480 mono8 stereo pairs (left/right image_raw + camera_info, one
stamp per pair = its publish time) from a few rendered scenes on a timer, each scene for
--pairs-per-scene pairs in a row (1: a new scene every pair, the worst case for correlation_node's
tracking of the previous decision's area; 30 at 30 Hz: an object that stays a second, as a live
rig sees it). A second node subscribes best_point, best_point/decision and /diagnostics.
--no-tracking turns correlation_node's tracking off (roi.track false: every pair matched on the
whole image), --no-scene-change-detection its comparison of block means before matching
(roi.detect_scene_change false), --max-undecided-matches N how many matches it may have
published without a decision before it matches the next pair (0: never waits),
--decision-wait-s sets how long the pair after a failed region waits for that pair's decision
(roi.decision_wait_s; 0 = matched on the whole image at once);
where pairs were matched is reported from its /diagnostics. --no-top-shape-fit turns
fuzzy_best_point_node's fit of the top to both images off (fit_top_shape false: the fit
delays the first pairs of each object).

Latency = arrival time in this process - pair header stamp (both CLOCK_REALTIME). A decision
(best_point/decision) is published for every pair the correlation node processes; a best point
only when one is chosen. Drop and stage figures are the differences of the nodes' /diagnostics
counters between the start and the end of each measurement (the chain is drained and fresh
diagnostics awaited at both ends).

Per-pair stages: the benchmark subscribes each node's per-pair timing (nodes/pair_timing.py;
a node measures and sends it only while subscribed, --no-breakdown leaves it off) and splits
every decided pair's latency into stages that add up to it (chain/latency_stages.py): p50 / p99
/ max of each, and for the pairs above the p99 which stage was furthest above its median.

Before measuring, pairs are published until the first decision arrives (the fuzzy node compiles
or loads its numba kernels at start), then for --warm-up seconds at each rate.
Markdown tables go to stdout, progress to stderr. Timings on a shared machine are noisy.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import statistics
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO_ROOT))

from chain.latency_stages import (  # noqa: E402
    PairStages,
    breakdown_markdown,
    fuzzy_free_times,
    pair_stages,
)
from chain.processes import ProcessGroup, wait_for  # noqa: E402
from chain.ros_domains import exported_domain_id  # noqa: E402

PACKAGE = 'stereo_fuzzy_perception'
NODES = ('stereo_sync_node', 'correlation_node', 'fuzzy_best_point_node')
DEMO_PARAMS = REPO_ROOT / 'chain' / 'demo_params.yaml'
# What the default rig needs when chain/demo_params.yaml is absent (disparities 37-86 px).
FALLBACK_OVERRIDES = {'correlation_node': ('min_disparity:=32', 'disparity_range:=64')}
# Measured as live cameras run: the correlation node works on the newest pair only (the demo
# replays with a deeper queue so no recorded scene is lost, which adds queueing latency).
LIVE_OVERRIDES = {'correlation_node': ('input_queue_depth:=1',)}
INPUT_TOPICS = ('left/image_raw', 'left/camera_info', 'right/image_raw', 'right/camera_info')
# /diagnostics status names (`<node name>: <what>`, see each node's _publish_diagnostics).
SYNC_STATUS = 'stereo_sync_node: stereo pairing'
CORRELATION_STATUS = 'correlation_node: correlation'
FUZZY_STATUS = 'fuzzy_best_point_node: best point'
SYNC_COUNTERS = ('pairs in', 'pairs out', 'pairs dropped', 'received left/image_raw',
                 *(f'unpaired {topic}' for topic in INPUT_TOPICS))
CORRELATION_COUNTERS = ('pairs received', 'pairs processed', 'dropped superseded',
                        'pairs matched in the tracked area')
WHOLE_IMAGE_PREFIX = 'pairs matched whole: '
DECISION_WAIT_PREFIX = 'decisions waited for after a failed region: '
# correlation_node's counts of its block-mean comparison and of the regions found in matches
TRACKING_COUNTERS = ('periodic whole images skipped, image unchanged outside the area',
                     'regions found in whole-image matches',
                     'pairs matched in a region found in whole-image matches')
# Each node's per-pair timing (nodes/pair_timing.py), in NODES order; the nodes run at the root.
TIMING_TOPICS = ('/pair/timing', '/matches/timing', '/best_point/timing')
SCENE_OBJECTS = ('cubic_square', 'cylinder', 'cubic_rectangle', 'circle')


def progress(text: str) -> None:
    """Print a progress line to stderr."""
    print(f'[chain-latency] {text}', file=sys.stderr, flush=True)


# --- input pairs --------------------------------------------------------------------------------

@dataclass
class EncodedPair:
    """The four messages of one rendered scene, encoded once; only their stamps change."""

    left_image: Any
    left_info: Any
    right_image: Any
    right_info: Any

    def messages(self) -> tuple[Any, Any, Any, Any]:
        """Return the messages in INPUT_TOPICS order."""
        return self.left_image, self.left_info, self.right_image, self.right_info


def render_pairs(count: int) -> list[EncodedPair]:
    """Render `count` scenes (mono8, 640x480, default rig) and encode them as messages."""
    from std_msgs.msg import Header
    from stereo_fuzzy_perception.nodes.conversions import (
        array_to_image,
        calibration_to_camera_info,
    )
    from stereo_fuzzy_perception.simulation.scene_renderer import render_scene

    pairs = []
    for index in range(count):
        frame = render_scene(100 + index, SCENE_OBJECTS[index % len(SCENE_OBJECTS)],
                             encoding='mono8')
        calibration = frame.calibration
        left_header = Header(frame_id=calibration.left.frame_id)
        right_header = Header(frame_id=calibration.right.frame_id)
        pairs.append(EncodedPair(
            array_to_image(frame.left, 'mono8', left_header),
            calibration_to_camera_info(calibration.left, left_header),
            array_to_image(frame.right, 'mono8', right_header),
            calibration_to_camera_info(calibration.right, right_header)))
    return pairs


class PairPublisher:
    """Publish the pairs in turn on a timer of its own node, executor and thread."""

    def __init__(self, context: Any, pairs: list[EncodedPair], pairs_per_scene: int = 1) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import CameraInfo, Image

        self.node = rclpy.create_node('chain_latency_publisher', context=context)
        # Reliable matches both a reliable and a best-effort (sensor data) subscription.
        profile = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5,
                             reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.VOLATILE)
        self.publishers = [
            self.node.create_publisher(Image if 'image' in topic else CameraInfo, topic, profile)
            for topic in INPUT_TOPICS]
        self.pairs = pairs
        self.pairs_per_scene = pairs_per_scene
        self.published_ns: list[int] = []
        self.publish_ms: list[float] = []
        self._timer: Any = None
        self._next = 0
        self.first_pair = 0
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self.executor.spin, name='pair_publisher',
                                        daemon=True)
        self._thread.start()

    def matched(self) -> bool:
        """Return True when every input topic has a subscriber."""
        return all(publisher.get_subscription_count() > 0 for publisher in self.publishers)

    def start(self, rate_hz: float) -> None:
        """Start publishing at `rate_hz` [Hz]; the published stamps restart empty."""
        self.stop()
        self.published_ns = []
        self.publish_ms = []
        self.first_pair = self._next  # pairs of a scene are counted across starts
        self._timer = self.node.create_timer(1.0 / rate_hz, self._publish_pair)

    def stop(self) -> None:
        """Stop publishing (the timer is cancelled, then destroyed)."""
        if self._timer is not None:
            self._timer.cancel()
            self.node.destroy_timer(self._timer)
            self._timer = None

    def _publish_pair(self) -> None:
        from builtin_interfaces.msg import Time

        pair = self.pairs[(self._next // self.pairs_per_scene) % len(self.pairs)]
        self._next += 1
        stamp_ns = time.time_ns()
        stamp = Time(sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000)
        for publisher, message in zip(self.publishers, pair.messages(), strict=True):
            message.header.stamp = stamp
            publisher.publish(message)
        self.published_ns.append(stamp_ns)
        self.publish_ms.append((time.time_ns() - stamp_ns) * 1e-6)

    def close(self) -> None:
        """Stop publishing and the executor thread, and destroy the node."""
        self.stop()
        self.executor.shutdown()
        self._thread.join(timeout=5.0)
        self.node.destroy_node()


# --- outputs ------------------------------------------------------------------------------------

@dataclass
class Diagnostics:
    """The newest values of one node's diagnostics status, and when they arrived."""

    values: dict[str, str] = field(default_factory=dict)
    stamp_ns: int = 0
    samples: list[dict[str, str]] = field(default_factory=list)


class ChainMonitor:
    """Record the arrival time of every best point and decision, and the nodes' diagnostics."""

    def __init__(self, context: Any, breakdown: bool = True) -> None:
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import PointStamped
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

        from stereo_fuzzy_msgs.msg import FuzzyDecision

        self.node = rclpy.create_node('chain_latency_monitor', context=context)
        results = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=50,
                             reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.VOLATILE)
        self.best_points: dict[int, int] = {}  # stamp [ns] -> arrival [ns]
        self.decisions: dict[int, int] = {}
        self.statuses: dict[int, str] = {}
        self.diagnostics: dict[str, Diagnostics] = {}
        self.subscriptions = [
            self.node.create_subscription(PointStamped, 'best_point', self._on_best_point,
                                          results),
            self.node.create_subscription(FuzzyDecision, 'best_point/decision',
                                          self._on_decision, results),
        ]
        self.diagnostics_subscription = self.node.create_subscription(
            DiagnosticArray, '/diagnostics', self._on_diagnostics, results)
        # Each node's per-pair timing (nodes/pair_timing.py), sent only while subscribed.
        self.timing: dict[str, dict[int, dict[str, str]]] = {name: {} for name in NODES}
        self.timing_subscriptions = [
            self.node.create_subscription(DiagnosticArray, topic, self._on_timing, results)
            for topic in (TIMING_TOPICS if breakdown else ())]
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)

    def spin(self, timeout: float) -> None:
        """Run the callbacks that are ready, waiting at most `timeout` [s]."""
        self.executor.spin_once(timeout_sec=timeout)

    def spin_for(self, seconds: float) -> None:
        """Run callbacks for `seconds` [s]."""
        deadline = time.monotonic() + seconds
        while (remaining := deadline - time.monotonic()) > 0:
            self.spin(min(0.05, remaining))

    def matched(self) -> bool:
        """Return True when every output topic and every node's diagnostics have a publisher."""
        return (all(sub.get_publisher_count() > 0
                    for sub in (*self.subscriptions, *self.timing_subscriptions))
                and self.diagnostics_subscription.get_publisher_count() >= len(NODES))

    @staticmethod
    def _stamp_ns(header: Any) -> int:
        return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)

    def _on_best_point(self, msg: Any) -> None:
        self.best_points[self._stamp_ns(msg.header)] = time.time_ns()

    def _on_decision(self, msg: Any) -> None:
        stamp_ns = self._stamp_ns(msg.header)
        self.decisions[stamp_ns] = time.time_ns()
        self.statuses[stamp_ns] = str(msg.status)

    def _on_timing(self, msg: Any) -> None:
        for status in msg.status:
            if status.name in self.timing:
                self.timing[status.name][self._stamp_ns(msg.header)] = {
                    value.key: value.value for value in status.values}

    def _on_diagnostics(self, msg: Any) -> None:
        for status in msg.status:
            record = self.diagnostics.setdefault(status.name, Diagnostics())
            record.values = {value.key: value.value for value in status.values}
            record.stamp_ns = time.time_ns()
            record.samples.append(record.values)

    def fresh_diagnostics(self, after_ns: int, timeout: float) -> dict[str, dict[str, str]]:
        """Wait for every node's diagnostics published after `after_ns`; return their values."""
        names = (SYNC_STATUS, CORRELATION_STATUS, FUZZY_STATUS)
        wait_for(lambda: all(name in self.diagnostics
                             and self.diagnostics[name].stamp_ns > after_ns for name in names),
                 timeout, 'fresh /diagnostics from every node', self.spin)
        return {name: dict(self.diagnostics[name].values) for name in names}

    def close(self) -> None:
        """Shut the executor down and destroy the node."""
        self.executor.shutdown()
        self.node.destroy_node()


# --- one measurement ----------------------------------------------------------------------------

@dataclass
class Measurement:
    """What one rate produced."""

    rate_hz: float
    duration_s: float
    published: int
    publish_rate_hz: float
    publish_ms_p99: float
    decisions: int
    best_points: int
    decision_latency_ms: list[float]
    decided_index: list[int]  # each decided pair's index among those published
    first_pair: int  # the publisher's count of pairs before the first one measured
    best_point_latency_ms: list[float]
    sync: dict[str, int]
    correlation: dict[str, int]
    fuzzy: dict[str, int]
    correlation_mean_ms: float | None
    stage_ms: dict[str, float]
    statuses: dict[str, int]
    pair_stages: list[PairStages]


def counter_deltas(before: dict[str, str], after: dict[str, str],
                   keys: tuple[str, ...]) -> dict[str, int]:
    """Return after - before of integer diagnostic values."""
    return {key: int(after.get(key, 0)) - int(before.get(key, 0)) for key in keys}


def correlation_mean_ms(before: dict[str, str], after: dict[str, str]) -> float | None:
    """Return the mean processing time of the pairs processed between two reports [ms]."""
    processed = int(after['pairs processed']) - int(before['pairs processed'])
    if processed <= 0:
        return None
    total = (float(after['mean processing time [ms]']) * int(after['pairs processed'])
             - float(before['mean processing time [ms]']) * int(before['pairs processed']))
    return total / processed


def stage_means(samples: list[dict[str, str]]) -> dict[str, float]:
    """Average the `last <stage> time [ms]` values sampled by the correlation node's reports."""
    stages: dict[str, list[float]] = {}
    for values in samples:
        for key, value in values.items():
            if key.startswith('last ') and key.endswith(' time [ms]'):
                stages.setdefault(key[len('last '):-len(' time [ms]')], []).append(float(value))
    return {stage: statistics.fmean(values) for stage, values in stages.items()}


def drain(monitor: ChainMonitor, publisher: PairPublisher, timeout: float) -> None:
    """Wait until the last published pair was decided (or `timeout` [s], if it was dropped)."""
    if not publisher.published_ns:
        return
    last = publisher.published_ns[-1]
    with contextlib.suppress(TimeoutError):
        wait_for(lambda: last in monitor.decisions, timeout, 'the last pair to be decided',
                 monitor.spin)


def measure(monitor: ChainMonitor, publisher: PairPublisher, group: ProcessGroup,
            rate_hz: float, warm_up_s: float, duration_s: float) -> Measurement:
    """Warm up at `rate_hz`, then publish for `duration_s` [s] and collect the figures."""
    progress(f'{rate_hz:g} Hz: warm-up {warm_up_s:g} s')
    publisher.start(rate_hz)
    monitor.spin_for(warm_up_s)
    publisher.stop()
    drain(monitor, publisher, 5.0)
    before = monitor.fresh_diagnostics(time.time_ns(), 10.0)
    monitor.diagnostics[CORRELATION_STATUS].samples = []
    progress(f'{rate_hz:g} Hz: measuring {duration_s:g} s')
    publisher.start(rate_hz)
    start = time.monotonic()
    while time.monotonic() - start < duration_s:
        monitor.spin(0.05)
        if group.exited():
            raise RuntimeError(f'{group.exited()[0].name} exited during the measurement')
    publisher.stop()
    elapsed = time.monotonic() - start
    drain(monitor, publisher, 5.0)
    after = monitor.fresh_diagnostics(time.time_ns(), 10.0)
    stage_samples = list(monitor.diagnostics[CORRELATION_STATUS].samples)

    published = list(publisher.published_ns)
    decided = [stamp for stamp in published if stamp in monitor.decisions]
    chosen = [stamp for stamp in published if stamp in monitor.best_points]
    fuzzy_free = fuzzy_free_times(monitor.timing[NODES[2]])
    statuses: dict[str, int] = {}
    for stamp in decided:
        statuses[monitor.statuses[stamp]] = statuses.get(monitor.statuses[stamp], 0) + 1
    return Measurement(
        rate_hz=rate_hz, duration_s=elapsed, published=len(published),
        publish_rate_hz=(len(published) - 1) / max((published[-1] - published[0]) * 1e-9, 1e-9)
        if len(published) > 1 else 0.0,
        publish_ms_p99=percentile(publisher.publish_ms, 99),
        decisions=len(decided), best_points=len(chosen),
        decision_latency_ms=[(monitor.decisions[s] - s) * 1e-6 for s in decided],
        decided_index=[index for index, stamp in enumerate(published)
                       if stamp in monitor.decisions],
        first_pair=publisher.first_pair,
        best_point_latency_ms=[(monitor.best_points[s] - s) * 1e-6 for s in chosen],
        sync=counter_deltas(before[SYNC_STATUS], after[SYNC_STATUS], SYNC_COUNTERS),
        correlation=counter_deltas(
            before[CORRELATION_STATUS], after[CORRELATION_STATUS],
            CORRELATION_COUNTERS + TRACKING_COUNTERS
            + tuple(key for key in after[CORRELATION_STATUS]
                    if key.startswith((WHOLE_IMAGE_PREFIX, DECISION_WAIT_PREFIX)))),
        fuzzy=counter_deltas(before[FUZZY_STATUS], after[FUZZY_STATUS],
                             ('decisions made', 'decisions refused')),
        correlation_mean_ms=correlation_mean_ms(before[CORRELATION_STATUS],
                                                after[CORRELATION_STATUS]),
        stage_ms=stage_means(stage_samples), statuses=statuses,
        pair_stages=[stages for stamp in decided if (stages := pair_stages(
            stamp, monitor.decisions[stamp],
            {node: monitor.timing[node][stamp] for node in NODES
             if stamp in monitor.timing[node]}, fuzzy_free.get(stamp, 0))) is not None])


def percentile(values: list[float], q: float) -> float:
    """Return the q-th percentile (linear interpolation), NaN for no values."""
    return float(np.percentile(values, q)) if values else float('nan')


# --- report -------------------------------------------------------------------------------------

def print_tables(results: list[Measurement], params: str, machine: str) -> None:
    """Print the measurements as markdown tables."""
    print(f'\n### Chain latency (640x480 mono8, {params}; {machine})\n')
    print('| rate [Hz] | measured [s] | pairs published (achieved rate) | decisions | '
          'best points | decision latency p50 / p99 [ms] | best point latency p50 / p99 [ms] '
          '| max [ms] |')
    print('|---:|---:|---:|---:|---:|---:|---:|---:|')
    for r in results:
        latencies = r.best_point_latency_ms or r.decision_latency_ms
        print(f'| {r.rate_hz:g} | {r.duration_s:.1f} | {r.published} ({r.publish_rate_hz:.2f} Hz)'
              f' | {r.decisions} | {r.best_points} '
              f'| {percentile(r.decision_latency_ms, 50):.1f} / '
              f'{percentile(r.decision_latency_ms, 99):.1f} '
              f'| {percentile(r.best_point_latency_ms, 50):.1f} / '
              f'{percentile(r.best_point_latency_ms, 99):.1f} '
              f'| {max(latencies, default=float("nan")):.1f} |')

    print("\n### Where pairs went (differences of the nodes' /diagnostics counters)\n")
    print('| rate [Hz] | published | sync: left images received | sync: pairs in / out | '
          'sync: pairs dropped | sync: unpaired messages | correlation: received / processed '
          '| correlation: superseded | fuzzy: made / refused |')
    print('|---:|---:|---:|---:|---:|---:|---:|---:|---:|')
    for r in results:
        unpaired = sum(r.sync[f'unpaired {topic}'] for topic in INPUT_TOPICS)
        print(f'| {r.rate_hz:g} | {r.published} | {r.sync["received left/image_raw"]} '
              f'| {r.sync["pairs in"]} / {r.sync["pairs out"]} | {r.sync["pairs dropped"]} '
              f'| {unpaired} '
              f'| {r.correlation["pairs received"]} / {r.correlation["pairs processed"]} '
              f'| {r.correlation["dropped superseded"]} '
              f'| {r.fuzzy["decisions made"]} / {r.fuzzy["decisions refused"]} |')

    print('\n### Where correlation_node matched the pairs (tracked area, or the whole image and '
          'why)\n')
    print('| rate [Hz] | tracked area | whole image (reason: pairs) | after a failed region, '
          "that pair's decision waited for (outcome: pairs) | periodic skipped (unchanged) | "
          'regions found in whole-image matches / pairs matched in them |')
    print('|---:|---:|---|---|---:|---:|')
    for r in results:
        whole = ', '.join(f'{key[len(WHOLE_IMAGE_PREFIX):]}: {count}'
                          for key, count in r.correlation.items()
                          if key.startswith(WHOLE_IMAGE_PREFIX) and count)
        waits = ', '.join(f'{key[len(DECISION_WAIT_PREFIX):]}: {count}'
                          for key, count in r.correlation.items()
                          if key.startswith(DECISION_WAIT_PREFIX))
        print(f'| {r.rate_hz:g} | {r.correlation["pairs matched in the tracked area"]} '
              f'| {whole or "-"} | {waits or "-"} | {r.correlation[TRACKING_COUNTERS[0]]} '
              f'| {r.correlation[TRACKING_COUNTERS[1]]} / {r.correlation[TRACKING_COUNTERS[2]]} |')

    stages = list(dict.fromkeys(stage for r in results for stage in r.stage_ms))  # node order
    print('\n### Correlation node processing time [ms] (mean over the measurement; stages '
          'averaged over its once-a-second `last <stage> time` reports)\n')
    print('| rate [Hz] | mean per pair | ' + ' | '.join(stages) + ' |')
    print('|---:|---:|' + '---:|' * len(stages))
    for r in results:
        mean = '-' if r.correlation_mean_ms is None else f'{r.correlation_mean_ms:.1f}'
        print(f'| {r.rate_hz:g} | {mean} | '
              + ' | '.join(f'{r.stage_ms.get(stage, float("nan")):.1f}' for stage in stages)
              + ' |')

    print('\n### Benchmark side\n')
    print('| rate [Hz] | publish of one pair (4 messages) p99 [ms] | decision statuses |')
    print('|---:|---:|---|')
    for r in results:
        statuses = ', '.join(f'{name}: {count}' for name, count in sorted(r.statuses.items()))
        print(f'| {r.rate_hz:g} | {r.publish_ms_p99:.2f} | {statuses} |')

    for r in results:
        if r.pair_stages:
            print(f"\n## {r.rate_hz:g} Hz: per-pair stages (the nodes' per-pair timing topics)")
            print(breakdown_markdown(r.pair_stages))

    print('\n### Goals: p99 < 100 ms at 15 Hz with no pair dropped by the sync node; at 30 Hz '
          'p99 < 66 ms (two frame periods), none dropped by the sync node, >= 29 decisions '
          'per second\n')
    for r in results:
        latencies = r.best_point_latency_ms or r.decision_latency_ms
        p99 = percentile(latencies, 99)
        dropped = r.sync['pairs dropped'] + (r.published - r.sync['pairs out'])
        per_second = r.decisions / r.duration_s
        if r.rate_hz == 15:
            verdict = 'met' if p99 < 100 and dropped == 0 else 'NOT met'
        elif r.rate_hz == 30:
            verdict = 'met' if p99 < 66 and dropped == 0 and per_second >= 29 else 'NOT met'
        else:
            continue
        print(f'- {r.rate_hz:g} Hz: p99 {p99:.1f} ms, {per_second:.1f} decisions per second, '
              f'{dropped} pairs published but not paired by the sync node '
              f'({r.sync["pairs dropped"]} counted as dropped): **{verdict}**')


# --- main ---------------------------------------------------------------------------------------

def node_arguments(executable: str, tracking: bool = True,
                   decision_wait_s: float | None = None,
                   scene_change: bool = True,
                   max_undecided_matches: int | None = None,
                   top_shape_fit: bool = True) -> list[str]:
    """Return the --ros-args of a node: the demo parameter file, or the fallback overrides."""
    overrides: tuple[str, ...] = LIVE_OVERRIDES.get(executable, ())
    if executable == 'correlation_node' and not tracking:
        overrides = (*overrides, 'roi.track:=false')
    if executable == 'correlation_node' and not scene_change:
        overrides = (*overrides, 'roi.detect_scene_change:=false')
    if executable == 'correlation_node' and decision_wait_s is not None:
        overrides = (*overrides, f'roi.decision_wait_s:={decision_wait_s!r}')
    if executable == 'correlation_node' and max_undecided_matches is not None:
        overrides = (*overrides, f'max_undecided_matches:={max_undecided_matches}')
    if executable == 'fuzzy_best_point_node' and not top_shape_fit:
        overrides = (*overrides, 'fit_top_shape:=false')
    if DEMO_PARAMS.exists():
        files = ['--params-file', str(DEMO_PARAMS)]
    else:
        files, overrides = [], (*FALLBACK_OVERRIDES.get(executable, ()), *overrides)
    return [*files, *(part for value in overrides for part in ('-p', value))]


def run(args: argparse.Namespace) -> list[Measurement]:
    """Start the chain, measure every rate, stop the chain; return the measurements."""
    import rclpy

    progress(f'rendering {args.scenes} scenes')
    pairs = render_pairs(args.scenes)
    log_dir = Path(args.log_dir or tempfile.mkdtemp(prefix='chain_latency_'))
    with exported_domain_id() as domain_id:
        progress(f'ROS_DOMAIN_ID {domain_id}, node logs in {log_dir}')
        group = ProcessGroup(log_dir)
        context = rclpy.Context()
        rclpy.init(context=context, domain_id=domain_id)
        publisher: PairPublisher | None = None
        monitor: ChainMonitor | None = None
        try:
            monitor = ChainMonitor(context, not args.no_breakdown)
            publisher = PairPublisher(context, pairs, args.pairs_per_scene)
            for executable in NODES:
                group.start_node(PACKAGE, executable,
                                 *node_arguments(executable, not args.no_tracking,
                                                 args.decision_wait_s,
                                                 not args.no_scene_change_detection,
                                                 args.max_undecided_matches,
                                                 not args.no_top_shape_fit))
            wait_for(lambda: publisher.matched() and monitor.matched(), 60.0,
                     "the chain's subscriptions and publishers to match", monitor.spin, group)
            progress('publishing until the first decision (kernels warm)')
            publisher.start(min(args.rates))
            wait_for(lambda: bool(monitor.decisions), 180.0, 'the first decision', monitor.spin,
                     group)
            publisher.stop()
            return [measure(monitor, publisher, group, rate, args.warm_up, args.duration)
                    for rate in args.rates]
        finally:
            if publisher is not None:
                publisher.stop()
            exit_codes = group.stop_all()
            if publisher is not None:
                publisher.close()
            if monitor is not None:
                monitor.close()
            context.try_shutdown()
            progress('stopped: ' + ', '.join(f'{name} exit {code}'
                                             for name, code in exit_codes.items()))
            for process in group.processes:
                for line in process.error_lines()[:5]:
                    progress(f'{process.name}: {line}')


def main() -> None:
    """Measure the chain's latency at each rate and print markdown tables."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--rates', type=float, nargs='+', default=[15.0, 30.0],
                        help='pair rates to measure [Hz]')
    parser.add_argument('--duration', type=float, default=20.0,
                        help='measurement per rate [s]')
    parser.add_argument('--warm-up', type=float, default=3.0,
                        help='publishing before each measurement, not measured [s]')
    parser.add_argument('--scenes', type=int, default=4, help='rendered scenes published in turn')
    parser.add_argument('--pairs-per-scene', type=int, default=1,
                        help='pairs published of each scene before the next one')
    parser.add_argument('--no-tracking', action='store_true',
                        help="turn correlation_node's tracking of the decided area off")
    parser.add_argument('--decision-wait-s', type=float, metavar='S',
                        help="correlation_node's roi.decision_wait_s (default: the node's)")
    parser.add_argument('--no-scene-change-detection', action='store_true',
                        help="turn correlation_node's roi.detect_scene_change off")
    parser.add_argument('--max-undecided-matches', type=int, metavar='N',
                        help="correlation_node's max_undecided_matches (default: the node's; "
                        '0 = never wait for decisions)')
    parser.add_argument('--no-top-shape-fit', action='store_true',
                        help="turn fuzzy_best_point_node's fit_top_shape off")
    parser.add_argument('--no-breakdown', action='store_true',
                        help="do not subscribe the nodes' per-pair timing topics, so they "
                        'measure and send nothing extra')
    parser.add_argument('--log-dir', help="where the nodes' logs go (default: a temp folder)")
    parser.add_argument('--latencies', metavar='CSV',
                        help='also write every decided pair: rate, index, decision latency [ms], '
                        'index among the published pairs, its place in its scene (0 = first)')
    args = parser.parse_args()
    load_before = os.getloadavg()[0]
    results = run(args)
    machine = (f'{os.cpu_count()} CPUs, 1-min load average {load_before:.1f} before, '
               f'{os.getloadavg()[0]:.1f} after')
    # The transports decide what a large message's hop costs (README, "Large messages over DDS")
    profiles = os.environ.get('FASTRTPS_DEFAULT_PROFILES_FILE')
    machine += (f'; Fast DDS profile {Path(profiles).name}' if profiles
                else "; Fast DDS's default transports")
    params = (f'parameters {DEMO_PARAMS.relative_to(REPO_ROOT)}' if DEMO_PARAMS.exists()
              else 'node defaults + correlation_node min_disparity 32, disparity_range 64')
    params += (f', {args.pairs_per_scene} pairs per scene, tracking '
               + ('off' if args.no_tracking else 'on'))
    if args.decision_wait_s is not None:
        params += f', roi.decision_wait_s {args.decision_wait_s:g}'
    if args.no_scene_change_detection:
        params += ', roi.detect_scene_change false'
    if args.max_undecided_matches is not None:
        params += f', max_undecided_matches {args.max_undecided_matches}'
    if args.no_top_shape_fit:
        params += ', fit_top_shape false'
    print_tables(results, params, machine)
    if args.latencies:
        with open(args.latencies, 'w', encoding='utf-8') as output:
            output.write('rate_hz,pair,decision_latency_ms,published,pair_of_scene\n')
            for r in results:
                output.writelines(
                    f'{r.rate_hz:g},{index},{latency:.2f},{published},'
                    f'{(r.first_pair + published) % args.pairs_per_scene}\n'
                    for index, (latency, published) in enumerate(
                        zip(r.decision_latency_ms, r.decided_index, strict=True)))


if __name__ == '__main__':
    main()
