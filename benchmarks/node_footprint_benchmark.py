"""Footprint of each node: cold start (empty vs warm numba cache) and memory over 1,000 pairs.

    source scripts/env.sh
    nice python benchmarks/node_footprint_benchmark.py                 # both starts, 1,000 pairs
    nice python benchmarks/node_footprint_benchmark.py --pairs 200 --checkpoints 20 200

Issue #18 item 4. Starts fake_gantry (homing off, no faults), gantry_driver_node,
stereo_sync_node, correlation_node and fuzzy_best_point_node as processes (parameters from
chain/demo_params.yaml) in a ROS domain of their own, and plays bags/demo_scenes with
`bag play --loop` at once, twice:

1. Cold start, empty cache: NUMBA_CACHE_DIR is a new, empty folder, so correlation_node and
   fuzzy_best_point_node compile their kernels. Stopped after the first decision.
2. Cold start, warm cache: the same folder, now holding what run 1 compiled. This run goes on
   until --pairs decisions and samples every process's resident memory (VmRSS from
   /proc/<pid>/status) when the decision count reaches each of --checkpoints.

Per node and run: "subscribed" is the time from starting its process until its input
subscription is on the ROS graph (correlation_node and fuzzy_best_point_node subscribe only
once their kernels are compiled or loaded); "first output" until this process receives the
node's first output (pair, matches, best_point/decision; the driver's first
gantry/state with the controller connected). A node's first output also waits for the nodes
upstream of it. The memory goal: flat within 5 % between pair 100 and pair 1,000. Pairs are
counted as decisions received (pairs that went through the whole chain).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

REPO_ROOT = Path(__file__).resolve().parents[1]
if str(REPO_ROOT) not in sys.path:
    sys.path.insert(0, str(REPO_ROOT))

from benchmarks.soak_benchmark import (  # noqa: E402
    DEMO_BAG,
    DEMO_PARAMS,
    DRIVER,
    INPUT_TOPICS,
    PERCEPTION,
    PLAYER_DELAY_S,
    MemorySample,
    growth_pct,
    sample_memory,
)
from chain.processes import ProcessGroup, executable_path, wait_for  # noqa: E402
from chain.ros_domains import exported_domain_id  # noqa: E402

# node -> (the input topic it subscribes, the output topic this process watches)
NODE_TOPICS = {
    'stereo_sync_node': ('left/image_raw', 'pair'),
    'correlation_node': ('pair', 'matches'),
    'fuzzy_best_point_node': ('matches', 'best_point/decision'),
    'gantry_driver_node': ('best_point', 'gantry/state'),
}
GOAL_GROWTH_PCT = 5.0


def progress(text: str) -> None:
    """Print a progress line to stderr."""
    print(f'[footprint] {text}', file=sys.stderr, flush=True)


@dataclass
class StartTimes:
    """Seconds from each node's process start to its subscription and its first output."""

    subscribed_s: dict[str, float] = field(default_factory=dict)
    first_output_s: dict[str, float] = field(default_factory=dict)


@dataclass
class FootprintWatcher:
    """This process's node: first outputs of every node, and the decision count."""

    context: Any
    first_output_at: dict[str, float] = field(default_factory=dict)
    decisions: int = 0

    def __post_init__(self) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        from stereo_fuzzy_msgs.msg import FuzzyDecision, GantryState, StereoMatches, StereoPair

        self.node = rclpy.create_node('footprint_watcher', context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        reliable = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        # Raw: only their arrival counts, so nothing is decoded.
        self.node.create_subscription(StereoPair, 'pair',
                                      lambda _: self._first('stereo_sync_node'), reliable,
                                      raw=True)
        self.node.create_subscription(StereoMatches, 'matches',
                                      lambda _: self._first('correlation_node'), reliable,
                                      raw=True)
        self.node.create_subscription(FuzzyDecision, 'best_point/decision', self._on_decision,
                                      reliable, raw=True)
        self.node.create_subscription(GantryState, 'gantry/state', self._on_state, latched)

    def _first(self, node: str) -> None:
        self.first_output_at.setdefault(node, time.monotonic())

    def _on_decision(self, _: bytes) -> None:
        self.decisions += 1
        self._first('fuzzy_best_point_node')

    def _on_state(self, msg: Any) -> None:
        if msg.connected:
            self._first('gantry_driver_node')

    def subscribed(self, node_name: str, topic: str) -> bool:
        """Return True when `node_name` subscribes `topic` on the ROS graph."""
        return any(info.node_name == node_name
                   for info in self.node.get_subscriptions_info_by_topic(topic))

    def spin(self, timeout: float) -> None:
        """Run the callbacks that are ready, waiting at most `timeout` [s]."""
        self.executor.spin_once(timeout_sec=timeout)

    def close(self) -> None:
        """Shut the executor down and destroy the node."""
        self.executor.shutdown()
        self.node.destroy_node()


def start_chain(group: ProcessGroup, link: Path) -> dict[str, float]:
    """Start the gantry, the driver, the nodes and the looping player; return each node's
    process start time (monotonic) [s]."""
    params = ['--params-file', str(DEMO_PARAMS)]
    group.start_node(DRIVER, 'fake_gantry', *params, '-p', f'link_path:={link}',
                     '-p', 'homing_enabled:=false')
    wait_for(link.exists, 60.0, 'the simulated gantry pseudo-terminal', watch=group)
    started = {}
    for package, executable, extra in (
            (DRIVER, 'gantry_driver_node', ('-p', f'port:={link}')),
            (PERCEPTION, 'stereo_sync_node', ()),
            (PERCEPTION, 'correlation_node', ()),
            (PERCEPTION, 'fuzzy_best_point_node', ())):
        started[executable] = time.monotonic()
        group.start_node(package, executable, *params, *extra)
    return started


def run_once(label: str, cache_dir: Path, log_dir: Path, domain_id: int, rate: float,
             pairs: int, checkpoints: list[int]) -> tuple[StartTimes, list[MemorySample]]:
    """Start the chain with this numba cache; measure the start and, if pairs > 1, memory."""
    import rclpy

    os.environ['NUMBA_CACHE_DIR'] = str(cache_dir)
    group = ProcessGroup(log_dir)
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain_id)
    watcher = FootprintWatcher(context)
    times = StartTimes()
    memory: list[MemorySample] = []
    link = Path(tempfile.mkdtemp(prefix='footprint_gantry_')) / 'tty'
    try:
        progress(f'{label}: starting the chain (NUMBA_CACHE_DIR {cache_dir})')
        started = start_chain(group, link)
        group.start('bag_play', [executable_path(PERCEPTION, 'bag'), 'play', DEMO_BAG, '--loop',
                                 '--wait-for-subscribers', '--rate', str(rate),
                                 '--topics', *INPUT_TOPICS, '--delay', str(PLAYER_DELAY_S)])

        def everything_started() -> bool:
            now = time.monotonic()
            for node, (topic, _) in NODE_TOPICS.items():
                if node not in times.subscribed_s and watcher.subscribed(node, topic):
                    times.subscribed_s[node] = now - started[node]
            return (len(times.subscribed_s) == len(NODE_TOPICS)
                    and len(watcher.first_output_at) == len(NODE_TOPICS))

        wait_for(everything_started, 600.0, 'every node to subscribe and publish',
                 watcher.spin, group)
        times.first_output_s = {node: watcher.first_output_at[node] - started[node]
                                for node in NODE_TOPICS}
        progress(f'{label}: ' + ', '.join(f'{node} {seconds:.1f} s'
                                          for node, seconds in times.first_output_s.items()))
        pids = {process.name: process.process.pid for process in group.processes}
        pending = sorted(checkpoints)
        start = time.monotonic()
        while pairs > 1 and watcher.decisions < pairs:
            watcher.spin(0.05)
            while pending and watcher.decisions >= pending[0]:
                memory.append(sample_memory(pids, time.monotonic() - start,
                                            f'pair {pending.pop(0)}'))
                progress(f'{label}: {memory[-1].label} after {memory[-1].elapsed_s:.0f} s')
            if group.exited():
                gone = group.exited()[0]
                raise RuntimeError(f'{gone.name} exited with {gone.process.returncode}:\n'
                                   f'{gone.output()[-3000:]}')
        while pending and watcher.decisions >= pending[0]:
            memory.append(sample_memory(pids, time.monotonic() - start, f'pair {pending.pop(0)}'))
    finally:
        exit_codes = group.stop_all()
        watcher.close()
        context.try_shutdown()
        unclean = {name: code for name, code in exit_codes.items() if code != 0}
        if unclean:
            progress(f'{label}: processes did not exit cleanly: {unclean}')
    return times, memory


def print_report(cold: StartTimes, warm: StartTimes, memory: list[MemorySample],
                 args: argparse.Namespace, machine: str) -> None:
    """Print the figures as markdown tables."""
    print(f'\n### Cold start per node [s] (bags/demo_scenes looped at rate {args.rate:g}; '
          f'{machine})\n')
    print('| node | subscribed, empty numba cache | subscribed, warm cache | first output, empty '
          'cache | first output, warm cache |')
    print('|---|---:|---:|---:|---:|')
    for node in NODE_TOPICS:
        print(f'| {node} | {cold.subscribed_s.get(node, float("nan")):.1f} '
              f'| {warm.subscribed_s.get(node, float("nan")):.1f} '
              f'| {cold.first_output_s.get(node, float("nan")):.1f} '
              f'| {warm.first_output_s.get(node, float("nan")):.1f} |')
    if not memory:
        return
    names = list(memory[0].rss_kib)
    reference = reference_sample(memory)
    print('\n### Resident memory [MiB] (VmRSS) by pairs decided, warm-cache run\n')
    print('| process | ' + ' | '.join(sample.label for sample in memory)
          + f' | growth {reference.label} -> {memory[-1].label} '
          f'| goal (< {GOAL_GROWTH_PCT:g} %) |')
    print('|---|' + '---:|' * len(memory) + '---:|---|')
    for name in names:
        cells = ' | '.join(f'{sample.rss_kib.get(name, 0) / 1024:.1f}' for sample in memory)
        before, after = reference.rss_kib.get(name, 0), memory[-1].rss_kib.get(name, 0)
        growth = growth_pct(before, after)
        verdict = 'met' if growth < GOAL_GROWTH_PCT else 'NOT met'
        print(f'| {name} | {cells} | {growth:+.1f} % | {verdict} |')


def reference_sample(memory: list[MemorySample]) -> MemorySample:
    """Return the sample growth is measured from: pair 100 if taken, else the second one."""
    for sample in memory:
        if sample.label == 'pair 100':
            return sample
    return memory[1] if len(memory) > 1 else memory[0]


def main(argv: list[str] | None = None) -> int:
    """Measure both cold starts and the memory run; print markdown."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--pairs', type=int, default=1000,
                        help='decisions the warm-cache run goes on for')
    parser.add_argument('--checkpoints', type=int, nargs='+',
                        default=[1, 100, 250, 500, 750, 1000],
                        help='decision counts at which memory is sampled')
    parser.add_argument('--rate', type=float, default=2.0,
                        help='bag playback rate (the bag holds a scene a second)')
    parser.add_argument('--output', help="folder for the nodes' logs (default: a temp folder)")
    args = parser.parse_args(argv)
    output = Path(args.output or tempfile.mkdtemp(prefix='footprint_'))
    cache_dir = Path(tempfile.mkdtemp(prefix='footprint_numba_cache_'))
    load_before = os.getloadavg()[0]
    with exported_domain_id() as domain_id:
        progress(f'ROS_DOMAIN_ID {domain_id}, logs in {output}')
        cold, _ = run_once('empty cache', cache_dir, output / 'empty_cache', domain_id,
                           args.rate, 1, [])
        warm, memory = run_once('warm cache', cache_dir, output / 'warm_cache', domain_id,
                                args.rate, args.pairs,
                                [c for c in args.checkpoints if c <= args.pairs])
    machine = (f'{os.cpu_count()} CPUs, 1-min load average {load_before:.1f} before, '
               f'{os.getloadavg()[0]:.1f} after')
    print_report(cold, warm, memory, args, machine)
    return 0


if __name__ == '__main__':
    sys.exit(main())
