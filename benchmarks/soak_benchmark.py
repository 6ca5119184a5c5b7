"""Soak: the demo bag looped through the whole chain against a faulty simulated gantry.

    source scripts/env.sh
    nice python benchmarks/soak_benchmark.py                   # 30 minutes (issue #15)
    nice python benchmarks/soak_benchmark.py --duration-s 600  # 10 minutes
    nice python benchmarks/soak_benchmark.py --short           # 2.5 minutes, dense faults

Starts fake_gantry on a pty with fault injection (a dropped reply every --drop-every lines, a
garbled reply every --garble-every lines, the device vanishing after every --vanish-every
lines), gantry_driver_node, stereo_sync_node, correlation_node and fuzzy_best_point_node as
processes (as chain/demo.py does, parameters from chain/demo_params.yaml) in a ROS domain of
their own, then plays bags/demo_scenes with `bag play --loop` for --duration-s seconds. This
process plays the operator: whenever the driver reports `homing_required` (after every latched
fault and every reconnection) it calls gantry/home.

Checked at the end (exit code 1 when one fails):
- G-code: the driver's sent_lines_log equals fake_gantry's received_lines_log line for line, in
  order; no motion line follows itself (a re-sent line); at most 3 motion lines per best point.
- Decisions: the best_point/decision messages received equal the complete pairs played minus
  the drops the nodes count on /diagnostics (sync: dropped + unpaired; correlation: dropped);
  each stage's counters are printed too, and the camera-input messages the sync node missed
  (DDS-reported, exact; from stamp gaps, estimated), which explain a broken identity but never
  balance it.
- No process died, and every process exits 0 when stopped.
- Resident memory (VmRSS from /proc/<pid>/status, sampled every --sample-period-s) of every
  process grows by at most --max-rss-growth-pct from the end of the warm-up to the end.

A markdown report goes to stdout, progress to stderr, logs and both line logs to --output.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

REPO_ROOT = Path(__file__).resolve().parents[1]
if str(REPO_ROOT) not in sys.path:
    sys.path.insert(0, str(REPO_ROOT))

from chain.processes import ProcessGroup, executable_path, wait_for  # noqa: E402

DEMO_BAG = REPO_ROOT / 'bags' / 'demo_scenes'
DEMO_PARAMS = REPO_ROOT / 'chain' / 'demo_params.yaml'
PERCEPTION = 'stereo_fuzzy_perception'
DRIVER = 'cartesian_3p_driver'
INPUT_TOPICS = ('left/image_raw', 'left/camera_info', 'right/image_raw', 'right/camera_info')
SYNC_STATUS = 'stereo_sync_node: stereo pairing'
CORRELATION_STATUS = 'correlation_node: correlation'
FUZZY_STATUS = 'fuzzy_best_point_node: best point'
DRIVER_STATUS = 'gantry_driver_node: serial link'
# Lines the driver writes that are not motion (connection, homing, unlocking).
SYSTEM_LINES = ('$$', '$H', '$X', 'G21 G90 G94')
# lift_xy_descend plans at most three lines per target (gcode.plan_move).
MAX_LINES_PER_MOVE = 3
# The driver's settings for the soak: a $H whose reply is dropped must not hold the run for the
# default 120 s, and reconnections start quickly.
DRIVER_OVERRIDES = ('homing_timeout_s:=15.0', 'reconnect_initial_s:=0.2',
                    'reconnect_max_s:=2.0')
# The player waits this long after seeing the subscribers, so that every subscriber has also
# matched the player's publishers on a loaded machine; the first scenes are not lost [s].
PLAYER_DELAY_S = 5.0
# A gantry/home call unanswered this long is a driver defect (homing_timeout_s is 15 s) [s].
HOME_ANSWER_TIMEOUT_S = 45.0


def progress(text: str) -> None:
    """Print a progress line to stderr."""
    print(f'[soak] {text}', file=sys.stderr, flush=True)


# --- resident memory ------------------------------------------------------------------------

def read_rss_kib(pid: int) -> int | None:
    """Return the resident set size of a process [KiB] (VmRSS), or None when it is gone."""
    try:
        text = Path(f'/proc/{pid}/status').read_text()
    except OSError:
        return None
    for line in text.splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1])
    return None


@dataclass
class MemorySample:
    """The resident memory of every process at one moment."""

    elapsed_s: float
    label: str
    rss_kib: dict[str, int]


def sample_memory(processes: dict[str, int], elapsed_s: float, label: str = '') -> MemorySample:
    """Read the resident memory of the processes (name -> pid) that are still alive."""
    values = {name: read_rss_kib(pid) for name, pid in processes.items()}
    return MemorySample(elapsed_s, label,
                        {name: rss for name, rss in values.items() if rss is not None})


def growth_pct(before_kib: int, after_kib: int) -> float:
    """Return the relative growth from before to after [%]."""
    return 100.0 * (after_kib - before_kib) / before_kib if before_kib else float('nan')


def memory_problems(reference: MemorySample, end: MemorySample,
                    max_growth_pct: float) -> list[str]:
    """Return a line per process whose memory grew more than `max_growth_pct` [%]."""
    problems = []
    for name, before in reference.rss_kib.items():
        after = end.rss_kib.get(name)
        if after is None:
            problems.append(f'{name}: no memory sample at the end (process gone)')
        elif growth_pct(before, after) > max_growth_pct:
            problems.append(f'{name}: resident memory grew {growth_pct(before, after):.1f} % '
                            f'({before / 1024:.1f} -> {after / 1024:.1f} MiB) after '
                            f'{reference.label}, more than {max_growth_pct:g} %')
    return problems


# --- invariants -----------------------------------------------------------------------------

def is_motion(line: str) -> bool:
    """Return True for a G-code line that moves the machine (not a system or modal line)."""
    return line not in SYSTEM_LINES


def line_log_problems(sent: Sequence[str], received: Sequence[str],
                      best_points: int) -> list[str]:
    """Check the driver's sent lines against the controller's received lines.

    Args:
        sent: The driver's sent_lines_log, in order.
        received: The simulator's received_lines_log, in order.
        best_points: Best points the driver was given (each plans at most 3 motion lines).

    Returns:
        A line per violated rule; empty when the logs agree.
    """
    problems = []
    for index, (out, came) in enumerate(zip(sent, received, strict=False)):
        if out != came:
            problems.append(f'line {index + 1}: sent {out!r} but the controller received '
                            f'{came!r}')
            break
    if len(sent) != len(received):
        problems.append(f'{len(sent)} lines sent but {len(received)} received')
    for index in range(1, len(sent)):
        if is_motion(sent[index]) and sent[index] == sent[index - 1]:
            problems.append(f'line {index + 1} repeats line {index}: {sent[index]!r} (re-sent)')
            break
    motion = sum(1 for line in sent if is_motion(line))
    if motion > MAX_LINES_PER_MOVE * best_points:
        problems.append(f'{motion} motion lines sent for {best_points} best points: more than '
                        f'{MAX_LINES_PER_MOVE} per target (lines replayed?)')
    return problems


@dataclass
class PairAccounting:
    """Where the played pairs went, from the counts of this process and of /diagnostics."""

    played: int
    sync_received: int
    sync_pairs_out: int
    sync_dropped: int
    sync_unpaired: int
    correlation_received: int
    correlation_processed: int
    correlation_dropped: dict[str, int]
    fuzzy_decisions: int
    decisions_received: int
    # Camera-input messages the sync node missed (most on any topic): reported by DDS (exact)
    # and estimated from stamp gaps (any cause, queue overwrites included). Never counted as
    # drops: they explain a broken identity, they do not balance it.
    sync_inputs_lost: int = 0
    sync_inputs_estimated_lost: int = 0

    @property
    def counted_drops(self) -> int:
        """Pairs the nodes say they dropped."""
        return self.sync_dropped + self.sync_unpaired + sum(self.correlation_dropped.values())

    @property
    def expected_decisions(self) -> int:
        """Decisions owed: every played pair not counted as dropped."""
        return self.played - self.counted_drops


def pair_problems(accounting: PairAccounting) -> list[str]:
    """Return a line per broken link of the pair accounting; empty when every pair is
    decided or counted as dropped."""
    a = accounting
    problems = []
    if a.decisions_received != a.expected_decisions:
        problems.append(
            f'{a.decisions_received} decisions received, but {a.played} pairs played minus '
            f'{a.counted_drops} counted drops = {a.expected_decisions}')
    stages = (
        ('sync node received complete scenes', a.sync_received, a.played),
        ('correlation node received pairs', a.correlation_received, a.sync_pairs_out),
        ('fuzzy node decided pairs', a.fuzzy_decisions,
         a.correlation_processed),
        ('this process received decisions', a.decisions_received, a.fuzzy_decisions),
    )
    for what, got, owed in stages:
        if got != owed:
            problems.append(f'stage: {what} {got}, its input gave {owed}')
    if a.sync_received != a.played:
        problems.append(f'camera inputs the sync node missed: {a.sync_inputs_estimated_lost} '
                        f'estimated from stamp gaps, {a.sync_inputs_lost} reported lost by DDS')
    return problems


def diagnostic_int(values: dict[str, str], key: str) -> int:
    """Return an integer /diagnostics value, 0 when absent."""
    return int(values.get(key, '0') or 0)


def accounting_from(played: int, decisions: int,
                    diagnostics: dict[str, dict[str, str]]) -> PairAccounting:
    """Build the pair accounting from played and decided counts and the nodes' diagnostics."""
    sync = diagnostics.get(SYNC_STATUS, {})
    correlation = diagnostics.get(CORRELATION_STATUS, {})
    fuzzy = diagnostics.get(FUZZY_STATUS, {})
    return PairAccounting(
        played=played,
        # A player stopped within a scene leaves that scene's first messages received: count
        # the scenes every input arrived for, as for `played`.
        sync_received=min(diagnostic_int(sync, f'received {topic}') for topic in INPUT_TOPICS),
        sync_pairs_out=diagnostic_int(sync, 'pairs out'),
        sync_dropped=diagnostic_int(sync, 'pairs dropped'),
        # A scene that never paired leaves its other messages unpaired; the most on any topic
        # is the number of such scenes when each lost one message.
        sync_unpaired=max((diagnostic_int(sync, f'unpaired {topic}') for topic in INPUT_TOPICS),
                          default=0),
        correlation_received=diagnostic_int(correlation, 'pairs received'),
        correlation_processed=diagnostic_int(correlation, 'pairs processed'),
        correlation_dropped={key[len('dropped '):]: int(value)
                             for key, value in correlation.items()
                             if key.startswith('dropped ')},
        fuzzy_decisions=diagnostic_int(fuzzy, 'decisions made')
        + diagnostic_int(fuzzy, 'decisions refused'),
        decisions_received=decisions,
        sync_inputs_lost=max(diagnostic_int(sync, f'lost before delivery {topic}')
                             for topic in INPUT_TOPICS),
        sync_inputs_estimated_lost=max(
            diagnostic_int(sync, f'{topic} estimated lost (stamp gaps)')
            for topic in INPUT_TOPICS))


# --- the watcher ----------------------------------------------------------------------------

@dataclass
class Watcher:
    """This process's node: counts inputs and decisions, keeps diagnostics, homes the gantry."""

    context: Any
    input_counts: dict[str, int] = field(default_factory=lambda: dict.fromkeys(INPUT_TOPICS, 0))
    decisions: int = 0
    best_points: int = 0
    diagnostics: dict[str, dict[str, str]] = field(default_factory=dict)
    diagnostics_at: dict[str, float] = field(default_factory=dict)
    state: Any = None
    home_calls: int = 0
    home_failures: list[str] = field(default_factory=list)
    home_unanswered: int = 0

    def __post_init__(self) -> None:
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import PointStamped
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import CameraInfo, Image
        from std_srvs.srv import Trigger

        from stereo_fuzzy_msgs.msg import FuzzyDecision, GantryState

        self.node = rclpy.create_node('soak_watcher', context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        reliable = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        for topic in INPUT_TOPICS:
            # Raw: only counted, never decoded, so this process stays light.
            message_type = Image if topic.endswith('image_raw') else CameraInfo
            self.node.create_subscription(message_type, topic,
                                          lambda _, topic=topic: self._count(topic), reliable,
                                          raw=True)
        self.node.create_subscription(FuzzyDecision, 'best_point/decision', self._on_decision,
                                      reliable, raw=True)
        self.node.create_subscription(PointStamped, 'best_point', self._on_best_point, reliable,
                                      raw=True)
        self.node.create_subscription(GantryState, 'gantry/state', self._on_state, latched)
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics,
                                      reliable)
        self.home_client = self.node.create_client(Trigger, 'gantry/home')
        self._trigger = Trigger
        self._home_future: Any = None
        self._next_home_at = 0.0
        self._home_deadline = 0.0

    def _count(self, topic: str) -> None:
        self.input_counts[topic] += 1

    def _on_decision(self, _: bytes) -> None:
        self.decisions += 1

    def _on_best_point(self, _: bytes) -> None:
        self.best_points += 1

    def _on_state(self, msg: Any) -> None:
        self.state = msg

    def _on_diagnostics(self, msg: Any) -> None:
        for status in msg.status:
            self.diagnostics[status.name] = {value.key: value.value for value in status.values}
            self.diagnostics_at[status.name] = time.monotonic()

    @property
    def played(self) -> int:
        """Complete scenes seen: every input topic carried one message for each."""
        return min(self.input_counts.values())

    def spin(self, timeout: float) -> None:
        """Run the callbacks that are ready, waiting at most `timeout` [s]."""
        self.executor.spin_once(timeout_sec=timeout)

    def spin_and_operate(self, timeout: float) -> None:
        """Run the ready callbacks, then home the gantry if it needs it."""
        self.spin(timeout)
        self.operate()

    def homing_wanted(self) -> bool:
        """Return True when the driver reaches a controller that refuses motion until homed:
        after a latched fault or a reconnection (homing_required), or booted in Alarm."""
        state = self.state
        return bool(state is not None and state.state not in ('Disconnected', 'Home')
                    and (state.homing_required or state.state == 'Alarm'))

    def operate(self) -> None:
        """Call gantry/home when the driver asks for it and no call is running."""
        future = self._home_future
        if future is not None:
            if not future.done():
                if time.monotonic() > self._home_deadline:
                    # The driver never answered: a defect to report, then try again.
                    self.home_unanswered += 1
                    self._home_future = None
                return
            result = future.result()
            if result is None or not result.success:
                self.home_failures.append('no answer' if result is None else result.message)
            self._home_future = None
            return  # the next state report tells whether homing is still wanted
        now = time.monotonic()
        if self.homing_wanted() and now >= self._next_home_at \
                and self.home_client.service_is_ready():
            # At most one call a second: a refused call must not turn into a busy loop.
            self._next_home_at = now + 1.0
            self.home_calls += 1
            self._home_deadline = now + HOME_ANSWER_TIMEOUT_S
            self._home_future = self.home_client.call_async(self._trigger.Request())

    def close(self) -> None:
        """Shut the executor down and destroy the node."""
        self.executor.shutdown()
        self.node.destroy_node()


# --- the run --------------------------------------------------------------------------------

@dataclass
class SoakResult:
    """What one soak run measured."""

    duration_s: float
    memory: list[MemorySample]
    reference: MemorySample
    accounting: PairAccounting
    sent: list[str]
    received: list[str]
    best_points: int
    home_calls: int
    home_failures: list[str]
    home_unanswered: int
    driver: dict[str, str]
    died: list[str]
    exit_codes: dict[str, int]
    vanishes: int
    problems: list[str]


def start_chain(group: ProcessGroup, args: argparse.Namespace, link: Path, sent_log: Path,
                received_log: Path) -> None:
    """Start fake_gantry (with the faults), the driver and the three perception nodes."""
    params = ['--params-file', str(DEMO_PARAMS)]
    faults = {'drop_reply_every_lines': args.drop_every,
              'garble_reply_every_lines': args.garble_every,
              'vanish_every_lines': args.vanish_every,
              'vanish_duration_s': args.vanish_duration_s}
    group.start_node(DRIVER, 'fake_gantry', *params, '-p', f'link_path:={link}',
                     '-p', f'received_lines_log:={received_log}',
                     *(part for name, value in faults.items()
                       for part in ('-p', f'{name}:={value}')))
    wait_for(link.exists, 30.0, 'the simulated gantry pseudo-terminal', watch=group)
    group.start_node(DRIVER, 'gantry_driver_node', *params, '-p', f'port:={link}',
                     '-p', f'sent_lines_log:={sent_log}',
                     *(part for value in DRIVER_OVERRIDES for part in ('-p', value)))
    for executable in ('stereo_sync_node', 'correlation_node', 'fuzzy_best_point_node'):
        group.start_node(PERCEPTION, executable, *params)


def chain_ready(watcher: Watcher) -> bool:
    """Return True once the correlation and fuzzy nodes subscribed (kernels compiled)."""
    node = watcher.node
    return (node.count_subscribers('pair') > 0
            and node.count_subscribers('matches') > 0
            and node.count_subscribers('best_point') > 1)


def drained(watcher: Watcher) -> bool:
    """Return True when every pair the nodes took in has been decided or counted dropped."""
    accounting = accounting_from(watcher.played, watcher.decisions, watcher.diagnostics)
    correlation_done = (accounting.correlation_processed
                        + sum(accounting.correlation_dropped.values())
                        == accounting.correlation_received)
    return (correlation_done
            and accounting.fuzzy_decisions == accounting.correlation_processed
            and accounting.decisions_received == accounting.fuzzy_decisions)


def run(args: argparse.Namespace) -> SoakResult:
    """Run the soak and return what it measured and which invariants failed."""
    import rclpy

    output = Path(args.output or tempfile.mkdtemp(prefix='soak_'))
    output.mkdir(parents=True, exist_ok=True)
    sent_log, received_log = output / 'gcode_sent.log', output / 'gcode_received.log'
    for log in (sent_log, received_log):
        log.unlink(missing_ok=True)
    link = Path(tempfile.mkdtemp(prefix='soak_gantry_')) / 'tty'
    problems: list[str] = []
    memory: list[MemorySample] = []
    died: list[str] = []
    from chain.ros_domains import exported_domain_id

    with exported_domain_id() as domain_id:
        progress(f'ROS_DOMAIN_ID {domain_id}, logs in {output}')
        group = ProcessGroup(output / 'logs')
        context = rclpy.Context()
        rclpy.init(context=context, domain_id=domain_id)
        watcher = Watcher(context)
        try:
            start_chain(group, args, link, sent_log, received_log)
            wait_for(lambda: watcher.state is not None and watcher.state.state != 'Disconnected',
                     60.0, 'the driver to reach the simulated gantry', watcher.spin, group)
            progress('waiting for the numba kernels (every link of the chain)')
            wait_for(lambda: chain_ready(watcher), 300.0, 'every link of the chain',
                     watcher.spin_and_operate, group)
            group.start('bag_play', [executable_path(PERCEPTION, 'bag'), 'play', DEMO_BAG,
                                     '--loop', '--wait-for-subscribers',
                                     '--rate', str(args.rate), '--topics', *INPUT_TOPICS,
                                     '--delay', str(PLAYER_DELAY_S)])
            wait_for(lambda: watcher.played > 0, 120.0, 'the first scene played',
                     watcher.spin_and_operate, group)
            pids = {process.name: process.process.pid for process in group.processes}
            start = time.monotonic()
            memory.append(sample_memory(pids, 0.0, 'start'))
            reference: MemorySample | None = None
            next_sample = start + args.sample_period_s
            progress(f'playing {DEMO_BAG.name} in a loop for {args.duration_s:g} s')
            while (elapsed := time.monotonic() - start) < args.duration_s:
                watcher.spin_and_operate(0.05)
                if group.exited():
                    died = [f'{process.name} (exit {process.process.returncode})'
                            for process in group.exited()]
                    problems.append('died during the run: ' + ', '.join(died))
                    break
                if time.monotonic() >= next_sample:
                    next_sample += args.sample_period_s
                    label = ''
                    if reference is None and elapsed >= args.warm_up_s:
                        label = f'warm-up ({elapsed:.0f} s)'
                    memory.append(sample_memory(pids, elapsed, label))
                    if label:
                        reference = memory[-1]
                    if len(memory) % 6 == 0:
                        progress(f'{elapsed:.0f} s: {watcher.played} pairs played, '
                                 f'{watcher.decisions} decisions, {watcher.best_points} best '
                                 f'points, {watcher.home_calls} homings')
            elapsed = time.monotonic() - start
            memory.append(sample_memory(pids, elapsed, 'end'))
            if reference is None:
                reference = memory[0]
            progress('stopping the player and draining the chain')
            player = group.processes[-1]
            player.stop()
            # Diagnostics published a second after the last input are past every queue.
            quiet_since = time.monotonic() + 1.0
            statuses = (SYNC_STATUS, CORRELATION_STATUS, FUZZY_STATUS, DRIVER_STATUS)
            with contextlib.suppress(TimeoutError):
                wait_for(lambda: drained(watcher) and all(
                    watcher.diagnostics_at.get(name, 0.0) > quiet_since for name in statuses),
                    60.0, 'the chain to drain', watcher.spin)
        finally:
            exit_codes = group.stop_all()
            watcher.close()
            context.try_shutdown()
    accounting = accounting_from(watcher.played, watcher.decisions, watcher.diagnostics)
    sent = sent_log.read_text().splitlines() if sent_log.exists() else []
    received = received_log.read_text().splitlines() if received_log.exists() else []
    problems += line_log_problems(sent, received, watcher.best_points)
    problems += pair_problems(accounting)
    problems += memory_problems(reference, memory[-1], args.max_rss_growth_pct)
    if watcher.home_unanswered:
        problems.append(f'{watcher.home_unanswered} gantry/home calls unanswered after '
                        f'{HOME_ANSWER_TIMEOUT_S:g} s')
    unclean = {name: code for name, code in exit_codes.items() if code != 0}
    if unclean:
        problems.append(f'processes did not exit cleanly: {unclean}')
    gantry_log = next((p.output() for p in group.processes if p.name == 'fake_gantry'), '')
    return SoakResult(
        duration_s=elapsed, memory=memory, reference=reference, accounting=accounting,
        sent=sent, received=received, best_points=watcher.best_points,
        home_calls=watcher.home_calls, home_failures=watcher.home_failures,
        home_unanswered=watcher.home_unanswered,
        driver=watcher.diagnostics.get(DRIVER_STATUS, {}), died=died, exit_codes=exit_codes,
        vanishes=gantry_log.count('device disappears'), problems=problems)


# --- report ---------------------------------------------------------------------------------

def print_report(result: SoakResult, args: argparse.Namespace, machine: str) -> None:
    """Print the run as markdown."""
    a = result.accounting
    received = len(result.received)
    print(f'\n### Soak: {result.duration_s / 60:.1f} min of bags/demo_scenes looped at rate '
          f'{args.rate:g} ({machine})\n')
    print('| check | figure | verdict |')
    print('|---|---|---|')
    lines_ok = not line_log_problems(result.sent, result.received, result.best_points)
    print(f'| G-code lines sent = received, in order, none re-sent | {len(result.sent)} sent, '
          f'{received} received ({sum(map(is_motion, result.sent))} motion lines for '
          f'{result.best_points} best points) | {"ok" if lines_ok else "FAILED"} |')
    pairs_ok = not pair_problems(a)
    print(f'| decisions = pairs - counted drops | {a.decisions_received} = {a.played} - '
          f'{a.counted_drops} (sync dropped {a.sync_dropped}, unpaired {a.sync_unpaired}, '
          f'correlation ' + ', '.join(f'{k} {v}' for k, v in a.correlation_dropped.items())
          + f'); camera inputs missed by the sync node: {a.sync_inputs_estimated_lost} '
          f'estimated (stamp gaps), {a.sync_inputs_lost} reported by DDS '
          f'| {"ok" if pairs_ok else "FAILED"} |')
    alive = not result.died and not any(result.exit_codes.values())
    print('| no process died, all exit 0 | '
          + ', '.join(f'{name} {code}' for name, code in result.exit_codes.items())
          + f' | {"ok" if alive else "FAILED"} |')
    print(f'| faults injected (every {args.drop_every} / {args.garble_every} / '
          f'{args.vanish_every} lines) | {received // args.drop_every if args.drop_every else 0}'
          f' dropped replies, {received // args.garble_every if args.garble_every else 0} '
          f'garbled, {result.vanishes} vanishes; driver reconnections '
          f'{result.driver.get("reconnections", "?")}, gantry/home calls {result.home_calls} '
          f'({len(result.home_failures)} failed, {result.home_unanswered} unanswered) '
          f'| {"ok" if not result.home_unanswered else "FAILED"} |')

    reference = result.reference
    start, end = result.memory[0], result.memory[-1]
    print(f'\n#### Resident memory [MiB] (VmRSS, sampled every {args.sample_period_s:g} s; '
          f'growth limit {args.max_rss_growth_pct:g} % after the warm-up)\n')
    print(f'| process | start | after {reference.label} | end ({end.elapsed_s:.0f} s) | max '
          '| growth after warm-up | verdict |')
    print('|---|---:|---:|---:|---:|---:|---|')
    for name, before in reference.rss_kib.items():
        after = end.rss_kib.get(name)
        peak = max(sample.rss_kib.get(name, 0) for sample in result.memory)
        first = start.rss_kib.get(name)
        growth = growth_pct(before, after) if after else float('nan')
        verdict = 'ok' if after and growth <= args.max_rss_growth_pct else 'FAILED'
        print(f'| {name} | {first / 1024 if first else float("nan"):.1f} | {before / 1024:.1f} '
              f'| {after / 1024 if after else float("nan"):.1f} | {peak / 1024:.1f} '
              f'| {growth:+.1f} % | {verdict} |')
    if result.problems:
        print('\n#### Failed\n')
        for problem in result.problems:
            print(f'- {problem}')
    else:
        print('\nEvery invariant held.')


def build_parser() -> argparse.ArgumentParser:
    """Return the command-line parser."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--duration-s', type=float, default=1800.0,
                        help='how long the bag plays [s] (issue #15: 30 minutes)')
    parser.add_argument('--short', action='store_true',
                        help='development run: 150 s, 30 s warm-up, faults every few dozen '
                             'lines (overrides those options)')
    parser.add_argument('--rate', type=float, default=1.0,
                        help='bag playback rate (the bag holds a scene a second)')
    parser.add_argument('--warm-up-s', type=float, default=120.0,
                        help='memory grows freely this long after the player starts [s]')
    parser.add_argument('--sample-period-s', type=float, default=10.0,
                        help='resident memory sampling period [s]')
    parser.add_argument('--max-rss-growth-pct', type=float, default=10.0,
                        help='largest memory growth from the warm-up to the end [%%]')
    parser.add_argument('--drop-every', type=int, default=211,
                        help='fake_gantry drops its reply to every n-th line (0 = off)')
    parser.add_argument('--garble-every', type=int, default=223,
                        help='fake_gantry garbles its reply to every n-th line (0 = off)')
    parser.add_argument('--vanish-every', type=int, default=599,
                        help='the device of fake_gantry vanishes after every n-th line (0 = off)')
    parser.add_argument('--vanish-duration-s', type=float, default=2.0,
                        help='how long the device stays away [s]')
    parser.add_argument('--output', help='folder for logs and line logs (default: a temp folder)')
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the soak; return 0 when every invariant held."""
    args = build_parser().parse_args(argv)
    if args.short:
        args.duration_s, args.warm_up_s, args.sample_period_s = 150.0, 30.0, 5.0
        args.drop_every, args.garble_every, args.vanish_every = 41, 43, 97
    load_before = os.getloadavg()[0]
    result = run(args)
    machine = (f'{os.cpu_count()} CPUs, 1-min load average {load_before:.1f} before, '
               f'{os.getloadavg()[0]:.1f} after')
    print_report(result, args, machine)
    return 1 if result.problems else 0


if __name__ == '__main__':
    sys.exit(main())
