"""Per-pair timing of a node on a debug topic, sent only while someone listens.

Each node of the chain can tell, for every pair it handled, when the pair arrived, when it left
and what the steps in between took, so a benchmark can split the chain's latency into stages
(benchmarks/chain_latency_benchmark.py). The topic sits next to the node's output
(topic_names: stereo_sync_node `pair/timing`, correlation_node `matches/timing`,
fuzzy_best_point_node `best_point/timing`). Nothing is measured beyond a clock read or two, and
nothing is built or published, while the topic has no subscriber: `active()` is one call into
rmw per pair.

One diagnostic_msgs/DiagnosticArray per pair: header.stamp is the pair's stamp, one status
named after the node, values:
  `<event> [ns]`  CLOCK_REALTIME of an event (comparable across processes on one machine):
                  `in` (the pair reached the node's code), `start`, `out` (after publishing),
                  and any the node adds (correlation_node: `matches out`);
  `<step> [ms]`   the duration of a step;
  `cpu [ms]`      CPU time of the thread that did the work between start and out (wall time
                  minus it is time the thread waited: for a core, for the GIL, for a lock);
  `gc [ms]`, `gc collections`  Python's garbage collection in this process between start and
                  out (any thread: a collection stops every thread);
  other keys      text (where the pair was matched, the decision's status).
"""

from __future__ import annotations

import gc
import threading
import time
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node

from stereo_fuzzy_perception.nodes import qos


class GarbageCollectionClock:
    """Sum the time the process spends in Python's garbage collector (gc.callbacks)."""

    def __init__(self) -> None:
        self.total_ns = 0
        self.collections = 0
        self._started_ns = 0
        self._installed = False
        self._lock = threading.Lock()

    def install(self) -> None:
        """Start counting (idempotent)."""
        with self._lock:
            if not self._installed:
                gc.callbacks.append(self._on_gc)
                self._installed = True

    def uninstall(self) -> None:
        """Stop counting."""
        with self._lock:
            if self._installed:
                gc.callbacks.remove(self._on_gc)
                self._installed = False

    def _on_gc(self, phase: str, info: dict[str, int]) -> None:
        # Runs with the GIL held and the collection in progress: no lock needed, no allocation
        # of note.
        if phase == 'start':
            self._started_ns = time.perf_counter_ns()
        elif self._started_ns:
            self.total_ns += time.perf_counter_ns() - self._started_ns
            self.collections += 1
            self._started_ns = 0

    def reading(self) -> tuple[int, int]:
        """Return (time in the collector so far [ns], collections so far)."""
        return self.total_ns, self.collections


class PairTimer:
    """The events and steps of one pair in one node; publish with PairTimingPublisher."""

    def __init__(self, garbage: GarbageCollectionClock, in_ns: int) -> None:
        self.values: dict[str, str] = {'in [ns]': str(in_ns)}
        self._garbage = garbage
        self._gc_start = garbage.reading()
        self._cpu_start = time.thread_time_ns()
        self.values['start [ns]'] = str(time.time_ns())
        self._step_start = time.perf_counter_ns()

    def step(self, name: str) -> None:
        """Close the step `name`: it lasted from the previous step's end (or start) until now."""
        now = time.perf_counter_ns()
        self.values[f'{name} [ms]'] = f'{(now - self._step_start) * 1e-6:.3f}'
        self._step_start = now

    def steps(self, durations_ms: dict[str, float]) -> None:
        """Record steps someone else timed [ms] (prefixed as given)."""
        for name, ms in durations_ms.items():
            self.values[f'{name} [ms]'] = f'{ms:.3f}'

    def event(self, name: str) -> None:
        """Record that `name` happened now (CLOCK_REALTIME)."""
        self.values[f'{name} [ns]'] = str(time.time_ns())

    def note(self, key: str, text: str) -> None:
        """Record a text value."""
        self.values[key] = text

    def finish(self) -> dict[str, str]:
        """Stamp `out`, CPU and garbage-collection time; return the values."""
        gc_ns, collections = self._garbage.reading()
        self.values['cpu [ms]'] = f'{(time.thread_time_ns() - self._cpu_start) * 1e-6:.3f}'
        self.values['gc [ms]'] = f'{(gc_ns - self._gc_start[0]) * 1e-6:.3f}'
        self.values['gc collections'] = str(collections - self._gc_start[1])
        self.values['out [ns]'] = str(time.time_ns())
        return self.values


class PairTimingPublisher:
    """Publish PairTimers on `topic` while it has a subscriber."""

    def __init__(self, node: Node, topic: str) -> None:
        self._node = node
        self.publisher = node.create_publisher(DiagnosticArray, topic, qos.RESULTS)
        self.garbage = GarbageCollectionClock()

    def start(self, in_ns: int) -> PairTimer | None:
        """Return a timer for a pair that reached the node at `in_ns`, or None (no listener)."""
        if self.publisher.get_subscription_count() == 0:
            self.garbage.uninstall()
            return None
        self.garbage.install()
        return PairTimer(self.garbage, in_ns)

    def publish(self, timer: PairTimer | None, stamp: Any) -> None:
        """Publish a finished timer for the pair stamped `stamp` (nothing for None)."""
        if timer is None:
            return
        status = DiagnosticStatus(
            name=self._node.get_name(), hardware_id=self._node.get_name(),
            values=[KeyValue(key=key, value=value) for key, value in timer.finish().items()])
        array = DiagnosticArray(status=[status])
        array.header.stamp = stamp
        self.publisher.publish(array)
