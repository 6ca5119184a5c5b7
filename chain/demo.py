"""The demo: the whole chain on a recorded bag and the simulated gantry.

Starts fake_gantry and every node as separate processes (parameters from chain/demo_params.yaml,
read natively through --ros-args --params-file), homes the gantry, records the outputs to a bag,
plays the demo bag, and prints a table per object: ground truth, best point, error, the G-code
lines sent and the gantry's final position. Writes a picture per object and exits non-zero if any
object fails. Run it with scripts/demo.sh.

A bag without ground truth (a real recording) is a regression run: every scene the chain decided
is reported and pictured, a scene passes when it got a best point that the gantry reached, and
`--compare REFERENCE_OUTPUTS_BAG` checks the best points against a reference run's
(chain/regression.py).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from stereo_fuzzy_perception.nodes.topic_names import (
    BEST_POINT,
    DECISION,
    MARKERS,
    MATCHES,
    PAIR,
    POINTS,
    STEREO_NAMESPACE,
    TF_STATIC,
    in_namespace,
)

from chain.processes import (
    REPO_ROOT,
    ProcessGroup,
    camera_remaps,
    executable_path,
    process_set,
    wait_for,
)
from chain.regression import (
    DEFAULT_TOLERANCE_MM,
    compare,
    format_comparison,
    scene_outcomes,
    write_reference,
)
from chain.ros_domains import reserved_domain_id

DEFAULT_BAG = REPO_ROOT / 'bags' / 'demo_scenes'
DEFAULT_PARAMS = REPO_ROOT / 'chain' / 'demo_params.yaml'
# What the outputs bag holds: the decisions and the gantry for the regression comparison, and
# the point cloud, the markers and the transforms that place them in `world`, so the bag opens
# in Foxglove or RViz with everything aligned (tests/test_whole_chain.py checks every frame).
OUTPUT_TOPICS = (BEST_POINT, DECISION, 'gantry/state', MARKERS,
                 in_namespace(STEREO_NAMESPACE, POINTS), TF_STATIC, '/tf')
# The demo and the regression test pass an object when its best point is within 8 mm of the
# top-face centre: the tool lands on the top face of the smallest object (3 cm across). The
# stricter 3 mm success rate of the chapter's Table 1 is in benchmarks/table1_benchmark.py.
DEMO_TOLERANCE_MM = 8.0


# (publishing node, topic, subscribing node): the links a scene travels from bag to gantry.
# Topic names as the chain description's defaults resolve them.
CHAIN_LINKS = (
    ('stereo_sync_node', in_namespace(STEREO_NAMESPACE, PAIR), 'correlation_node'),
    ('correlation_node', in_namespace(STEREO_NAMESPACE, MATCHES), 'fuzzy_best_point_node'),
    ('fuzzy_best_point_node', in_namespace('', BEST_POINT), 'gantry_driver_node'),
)


# The outputs bag's recorder must hear the first scene's decision too, or the regression
# comparison finds that scene missing.
RECORDER_LINKS = tuple(('fuzzy_best_point_node', in_namespace('', topic), 'bag_recorder')
                       for topic in ('best_point', 'best_point/decision'))


def missing_links(node: object, links: tuple[tuple[str, str, str], ...] = CHAIN_LINKS
                  ) -> list[str]:
    """Return the links (CHAIN_LINKS by default) that the ROS graph does not show yet, in
    words."""
    missing = []
    for publisher, topic, subscriber in links:
        publishers = {info.node_name for info in node.get_publishers_info_by_topic(topic)}
        subscribers = {info.node_name for info in node.get_subscriptions_info_by_topic(topic)}
        if publisher not in publishers or subscriber not in subscribers:
            missing.append(f'{publisher} -> {topic} -> {subscriber}')
    return missing


# (node, diagnostics key, topic, 'subscribers' = its writer's matched readers, to equal the
# graph's subscriptions of the topic; 'publishers' = its reader's matched writers, at least one)
MATCHED_ENDPOINTS = (
    ('stereo_sync_node', f'{PAIR} subscribers', in_namespace(STEREO_NAMESPACE, PAIR)),
    ('correlation_node', f'{PAIR} publishers', in_namespace(STEREO_NAMESPACE, PAIR)),
    ('correlation_node', f'{MATCHES} subscribers', in_namespace(STEREO_NAMESPACE, MATCHES)),
    ('fuzzy_best_point_node', f'{MATCHES} publishers', in_namespace(STEREO_NAMESPACE, MATCHES)),
    ('fuzzy_best_point_node', f'{BEST_POINT} subscribers', in_namespace('', BEST_POINT)),
)


class LatestDiagnostics:
    """The latest /diagnostics values of each node, by node name (hardware_id)."""

    def __init__(self, node: Any) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from stereo_fuzzy_parameters.qos import DIAGNOSTICS

        self.values: dict[str, dict[str, str]] = {}
        node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics,
                                 DIAGNOSTICS)

    def _on_diagnostics(self, array: Any) -> None:
        for status in array.status:
            self.values.setdefault(status.hardware_id, {}).update(
                {item.key: item.value for item in status.values})


def unmatched_links(node: Any, diagnostics: LatestDiagnostics) -> list[str]:
    """Return the MATCHED_ENDPOINTS whose node does not report them matched yet, in words."""
    unmatched = []
    for name, key, topic in MATCHED_ENDPOINTS:
        reported = diagnostics.values.get(name, {}).get(key)
        wanted = node.count_subscribers(topic) if key.endswith('subscribers') else 1
        if reported is None or int(reported) < wanted:
            unmatched.append(f'{name}: {key} {reported} of {wanted}')
    return unmatched


@dataclass
class ObjectResult:
    """The verdict on one object of the bag."""

    index: int
    stamp_ns: int
    ground_truth: list[float] | None
    best_point: list[float] | None
    error_mm: float | None
    horizontal_error_mm: float | None
    vertical_error_mm: float | None
    commanded: list[float] | None
    final_position: list[float] | None
    gcode_lines: list[str]
    status: str
    passed: bool


def _read_lines(path: Path) -> list[str]:
    return path.read_text().splitlines() if path.exists() else []


def _strip_log_prefix(line: str) -> str:
    """Drop a leading timestamp column from a sent/received line log, if the log has one."""
    head, _, rest = line.partition('\t')
    return rest if rest and head.replace('.', '', 1).isdigit() else line


class DemoRun:
    """One run of the chain over a bag: processes, monitor and verdicts."""

    def __init__(self, bag: Path, params_file: Path, output_dir: Path, tolerance_mm: float,
                 rate: float, timeout_s: float, quiet: bool = False) -> None:
        self.labelled = True  # known once the bag has played: did any ground truth arrive?
        self.bag = bag
        self.params_file = params_file
        self.output_dir = output_dir
        self.tolerance_mm = tolerance_mm
        self.rate = rate
        self.timeout_s = timeout_s
        self.quiet = quiet
        self.settle_timeout_s = 60.0
        self.params = yaml.safe_load(params_file.read_text())
        self.group = ProcessGroup(output_dir / 'logs')
        self.gantry_link = Path(tempfile.mkdtemp(prefix='stereo_fuzzy_gantry_')) / 'tty'
        self.sent_log = output_dir / 'gcode_sent.log'
        self.received_log = output_dir / 'gcode_received.log'

    # --- processes ---------------------------------------------------------------------------

    def start_chain(self) -> None:
        """Start the simulated gantry, the driver and the three perception nodes."""
        for log in (self.sent_log, self.received_log):
            log.unlink(missing_ok=True)
        # The processes of chain_without_hardware.launch.py, from the same description.
        processes = process_set('chain_without_hardware')
        arguments = processes.argument_values({'port': str(self.gantry_link),
                                               'params_file': str(self.params_file)})
        extra = {'fake_gantry': ['-p', f'received_lines_log:={self.received_log}'],
                 'gantry_driver_node': ['-p', f'sent_lines_log:={self.sent_log}']}
        for process in processes.processes:
            self.group.start_described(process, arguments, *extra.get(process.name, ()))
            if process.name == 'fake_gantry':
                wait_for(self.gantry_link.exists, 30.0, 'the simulated gantry pseudo-terminal',
                         watch=self.group)

    def start_recorder(self) -> Path:
        """Record the chain's outputs into a bag under the output folder."""
        outputs = self.output_dir / 'outputs_bag'
        if outputs.exists():
            for child in sorted(outputs.rglob('*'), reverse=True):
                child.unlink() if child.is_file() else child.rmdir()
            outputs.rmdir()
        self.group.start('bag_record', [executable_path('stereo_fuzzy_perception', 'bag'),
                                        'record', '-o', outputs, *OUTPUT_TOPICS])
        return outputs

    def start_player(self) -> None:
        """Play the demo bag once every topic it publishes has a subscriber."""
        self.group.start('bag_play', [executable_path('stereo_fuzzy_perception', 'bag'), 'play',
                                      self.bag, '--wait-for-subscribers',
                                      '--rate', str(self.rate), '--remap', *camera_remaps()],
                         one_shot=True)

    # --- the run -----------------------------------------------------------------------------

    def run(self) -> list[ObjectResult]:
        """Run the chain over the bag and return a verdict per object."""
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from std_srvs.srv import Trigger

        from chain.demo_monitor import DemoMonitor

        self.output_dir.mkdir(parents=True, exist_ok=True)
        context = rclpy.Context()
        rclpy.init(context=context)
        node = rclpy.create_node('demo_monitor', context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        monitor = DemoMonitor(node)

        def spin(timeout: float) -> None:
            executor.spin_once(timeout_sec=timeout)

        try:
            self._progress('starting the simulated gantry and the nodes')
            self.start_chain()
            # A controller with homing enabled boots in Alarm; the driver reports its state
            # (connected stays false until the preamble is acknowledged after homing).
            wait_for(lambda: monitor.latest_gantry_state is not None
                     and monitor.latest_gantry_state.state != 'Disconnected', 60.0,
                     'the driver to reach the simulated gantry', spin, self.group)
            self._progress('homing the gantry')
            home = node.create_client(Trigger, 'gantry/home')
            wait_for(home.service_is_ready, 30.0, 'the gantry/home service', spin, self.group)
            # The driver may report the controller's state a moment before its link accepts
            # requests ('not connected'): ask again until homing succeeds or time runs out.
            deadline = time.monotonic() + 60.0
            while True:
                future = home.call_async(Trigger.Request())
                wait_for(future.done, 120.0, 'homing to finish', spin, self.group)
                if future.result().success:
                    break
                if time.monotonic() >= deadline:
                    raise RuntimeError(f'homing failed: {future.result().message}')
                pause_until = time.monotonic() + 0.5
                while time.monotonic() < pause_until:
                    spin(0.05)
            wait_for(monitor.gantry_ready, 60.0, 'the gantry to be Idle after homing', spin,
                     self.group)
            self.lines_sent_at_start = monitor.latest_gantry_state.lines_sent
            self.start_recorder()
            diagnostics = LatestDiagnostics(node)
            # correlation_node and fuzzy_best_point_node create their endpoints only once their
            # numba kernels are compiled (cold-start times: the README's benchmark table). A
            # scene played before every link of the chain exists is lost at the first missing
            # link.
            try:
                wait_for(lambda: not missing_links(node, CHAIN_LINKS + RECORDER_LINKS), 180.0,
                         'every link of the chain (kernels compiled) and the recorder', spin,
                         self.group)
            except TimeoutError as error:
                missing = missing_links(node, CHAIN_LINKS + RECORDER_LINKS)
                raise TimeoutError(f'{error}; missing: {", ".join(missing)}') from None
            # On the graph is not yet connected: DDS matches each writer to each reader a little
            # later, and a message published before that is lost to that reader. The nodes say
            # in /diagnostics how many readers their writers reach and writers their readers
            # hear; play once those agree with the graph.
            wait_for(lambda: not unmatched_links(node, diagnostics), 60.0,
                     'DDS to connect every link of the chain', spin, self.group)
            self._progress(f'playing {self.bag.name}')
            self.start_player()
            player = self.group.processes[-1]
            deadline = time.monotonic() + self.timeout_s
            while player.running() and time.monotonic() < deadline:
                spin(0.1)
                self._progress_scenes(monitor)
            if player.running():
                raise TimeoutError(f'the bag did not finish playing in {self.timeout_s:.0f} s')
            if player.process.returncode != 0:
                raise RuntimeError(f'bag play failed:\n{player.output()[-3000:]}')
            expected = self._scenes(monitor)
            try:
                wait_for(lambda: self._all_settled(monitor, expected), self.settle_timeout_s,
                         'the last decisions and moves', spin, self.group)
            except TimeoutError as error:
                # What did not finish shows up as a failed object in the table.
                self._progress(str(error))
        finally:
            exit_codes = self.group.stop_all()
            node.destroy_node()
            executor.shutdown()
            context.try_shutdown()
        if not self.quiet and sys.stderr.isatty():
            print(file=sys.stderr)
        self.exit_codes = exit_codes
        return self._verdicts(monitor)

    def _scenes(self, monitor: object) -> list:
        """Return the scenes to judge, in stamp order: those with ground truth, or for a bag
        without any, every scene that reached the chain (a pair or a decision)."""
        labelled = [record for record in monitor.scenes.values()
                    if record.ground_truth is not None]
        self.labelled = bool(labelled)
        scenes = labelled or [record for record in monitor.scenes.values()
                              if record.pair is not None or record.decision is not None]
        return sorted(scenes, key=lambda record: record.stamp_ns)

    def _commanded(self, best_point: np.ndarray) -> np.ndarray:
        offset = float(self.params.get('gantry_driver_node', {}).get('ros__parameters', {})
                       .get('approach_offset_m', 0.0))
        return best_point + np.array([0.0, 0.0, offset])

    def _all_settled(self, monitor: object, expected: list) -> bool:
        for record in expected:
            if record.decision is None:
                return False
            if record.best_point is not None and monitor.idle_at(
                    self._commanded(record.best_point), 0.0005,
                    record.gantry_index_at_best_point) is None:
                return False
        return True

    def _verdicts(self, monitor: object) -> list[ObjectResult]:
        from chain.demo_pictures import draw_scene

        sent = [_strip_log_prefix(line) for line in _read_lines(self.sent_log)]
        results = []
        # Targets run one after another, so the lines sent between reaching the previous target
        # and reaching this one are this target's lines.
        lines_before = self.lines_sent_at_start
        for index, record in enumerate(self._scenes(monitor)):
            result, lines_before = self._verdict(index, record, monitor, sent, lines_before)
            results.append(result)
            reached = (None if record.best_point is None else monitor.idle_at(
                self._commanded(record.best_point), 0.0005, record.gantry_index_at_best_point))
            until = reached.index if reached is not None else record.gantry_index_at_best_point
            try:
                draw_scene(record, self.params, self.output_dir / f'object_{index:02d}.png',
                           f'scene {index}', monitor.gantry_path(until))
            except Exception as error:  # a picture must not lose the run's verdicts
                print(f'[demo] no picture of scene {index}: {error!r}', file=sys.stderr)
        return results

    def _verdict(self, index: int, record: object, monitor: object, sent: list[str],
                 lines_before: int) -> tuple[ObjectResult, int]:
        truth = record.ground_truth
        truth_list = None if truth is None else truth.tolist()
        if record.best_point is None:
            reason = (record.decision.status if record.decision is not None
                      else 'no decision (pair dropped, see the logs)')
            return ObjectResult(index, record.stamp_ns, truth_list, None, None, None, None,
                                None, None, [], f'no best point: {reason}', False), lines_before
        commanded = self._commanded(record.best_point)
        reached = monitor.idle_at(commanded, 0.0005, record.gantry_index_at_best_point)
        lines, lines_after = ([], lines_before) if reached is None else self._move_lines(
            commanded, sent, lines_before)
        error_mm = horizontal_mm = vertical_mm = None
        if truth is not None:
            error = record.best_point - truth
            error_mm = float(np.linalg.norm(error) * 1000)
            horizontal_mm = float(np.linalg.norm(error[:2]) * 1000)
            vertical_mm = float(abs(error[2]) * 1000)
        passed = reached is not None and (error_mm is None or error_mm <= self.tolerance_mm)
        if reached is None:
            status = f'gantry did not reach the best point ({monitor.driver_summary(record)})'
        elif error_mm is not None and error_mm > self.tolerance_mm:
            status = f'error above {self.tolerance_mm} mm'
        else:
            status = 'ok' if truth is not None else 'ok (no ground truth: reached)'
        result = ObjectResult(
            index, record.stamp_ns, truth_list, record.best_point.tolist(), error_mm,
            horizontal_mm, vertical_mm, commanded.tolist(),
            None if reached is None else reached.world_position.tolist(), lines, status, passed)
        return result, lines_after

    def _move_lines(self, commanded: np.ndarray, sent: list[str],
                    start: int) -> tuple[list[str], int]:
        """Return the lines of the move that ends at `commanded`, from `start` on in the sent
        log, and the index after them. Every approach ends with the line that brings Z to the
        goal height, so the move is everything up to the first such line."""
        driver = self.params.get('gantry_driver_node', {}).get('ros__parameters', {})
        offset = np.array(driver.get('machine_offset_mm', [0.0, 0.0, 0.0]), dtype=float)
        scale = np.array(driver.get('axis_scale_mm_per_m', [1000.0, 1000.0, 1000.0]),
                         dtype=float)
        goal_z_mm = float(offset[2] + scale[2] * commanded[2])
        for index in range(start, len(sent)):
            words = {word[0]: word[1:] for word in sent[index].split() if word[:1] in 'XYZ'}
            if 'Z' in words and abs(float(words['Z']) - goal_z_mm) <= 0.0015:
                return sent[start:index + 1], index + 1
        return sent[start:], len(sent)

    # --- progress ----------------------------------------------------------------------------

    def _progress(self, text: str) -> None:
        """Show a progress line: rewritten in place on a terminal, one line per change in a log."""
        if self.quiet or text == getattr(self, '_last_progress', None):
            return
        self._last_progress = text
        if sys.stderr.isatty():
            print(f'\r\033[K[demo] {text}', end='', file=sys.stderr, flush=True)
        else:
            print(f'[demo] {text}', file=sys.stderr, flush=True)

    def _progress_scenes(self, monitor: object) -> None:
        seen = sum(1 for record in monitor.scenes.values()
                   if record.ground_truth is not None or record.pair is not None)
        decided = sum(1 for record in monitor.scenes.values() if record.decision is not None)
        state = monitor.latest_gantry_state.state if monitor.latest_gantry_state else '?'
        self._progress(f'scenes played {seen}, decided {decided}, gantry {state}')


def format_table(results: list[ObjectResult]) -> str:
    """Return the per-object results as a markdown table."""
    def point(values: list[float] | None) -> str:
        return '-' if values is None else '(' + ', '.join(f'{v * 1000:.1f}' for v in values) + ')'

    lines = ['| # | ground truth [mm] | best point [mm] | error [mm] (xy / z) | gantry final '
             '[mm] | G-code sent | verdict |', '|---|---|---|---|---|---|---|']
    for result in results:
        error = '-' if result.error_mm is None else (
            f'{result.error_mm:.2f} ({result.horizontal_error_mm:.2f} / '
            f'{result.vertical_error_mm:.2f})')
        gcode = '<br>'.join(result.gcode_lines) or '-'
        lines.append(f'| {result.index} | {point(result.ground_truth)} | '
                     f'{point(result.best_point)} | {error} | {point(result.final_position)} | '
                     f'{gcode} | {result.status} |')
    return '\n'.join(lines)


def main(argv: list[str] | None = None) -> int:
    """Run the demo; return 0 when every object passed (and matched the reference, if any)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--bag', type=Path, default=DEFAULT_BAG, help='bag to play')
    parser.add_argument('--params', type=Path, default=DEFAULT_PARAMS,
                        help='ROS parameter file for every node')
    parser.add_argument('--output', type=Path, default=REPO_ROOT / 'output' / 'demo',
                        help='folder for pictures, logs, the outputs bag and results.json')
    parser.add_argument('--tolerance-mm', type=float, default=DEMO_TOLERANCE_MM,
                        help='largest best-point error that passes [mm]')
    parser.add_argument('--rate', type=float, default=0.5,
                        help='bag playback rate (the bags hold a scene a second)')
    parser.add_argument('--timeout', type=float, default=600.0,
                        help='longest time the bag may take to play [s]')
    parser.add_argument('--compare', type=Path, metavar='REFERENCE_OUTPUTS_BAG',
                        help="compare the best points with a reference run's outputs bag")
    parser.add_argument('--compare-tolerance-mm', type=float, default=DEFAULT_TOLERANCE_MM,
                        help='largest distance from the reference best point that passes [mm]')
    parser.add_argument('--write-reference', type=Path, metavar='PATH',
                        help="write this run's best points and decisions as a reference bag")
    arguments = parser.parse_args(argv)
    if arguments.write_reference is not None and arguments.write_reference.exists():
        parser.error(f'--write-reference {arguments.write_reference} exists; remove it first')
    if arguments.compare is not None and not arguments.compare.exists():
        parser.error(f'--compare {arguments.compare} does not exist')
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    with contextlib.ExitStack() as stack:
        if 'ROS_DOMAIN_ID' not in os.environ:
            # A ROS domain of its own: another chain on this machine (a second demo, a test)
            # would otherwise feed its best points and gantry states into this run.
            os.environ['ROS_DOMAIN_ID'] = str(stack.enter_context(reserved_domain_id()))
        run = DemoRun(arguments.bag, arguments.params, arguments.output,
                      arguments.tolerance_mm, arguments.rate, arguments.timeout)
        results = run.run()
    table = format_table(results)
    print(table)
    (arguments.output / 'results.json').write_text(
        json.dumps([asdict(result) for result in results], indent=2))
    failed = [result for result in results if not result.passed]
    what = 'objects' if run.labelled else 'scenes (no ground truth: best point reached)'
    print(f'\n{len(results) - len(failed)} of {len(results)} {what} passed '
          f'(tolerance {arguments.tolerance_mm} mm); pictures, logs and the outputs bag are in '
          f'{arguments.output}')
    report = table + '\n'
    outputs_bag = arguments.output / 'outputs_bag'
    mismatched = 0
    if arguments.compare is not None:
        rows = compare(scene_outcomes(arguments.compare), scene_outcomes(outputs_bag),
                       arguments.compare_tolerance_mm)
        comparison = format_comparison(rows)
        mismatched = sum(not row.passed for row in rows) + (0 if rows else 1)
        print(f'\ncompared with {arguments.compare}:\n{comparison}\n'
              f'{len(rows) - sum(not row.passed for row in rows)} of {len(rows)} scenes match '
              f'the reference (tolerance {arguments.compare_tolerance_mm:g} mm)')
        report += f'\n## Compared with {arguments.compare}\n\n{comparison}\n'
    (arguments.output / 'results.md').write_text(report)
    if arguments.write_reference is not None:
        def shown(path: Path) -> str:  # repository paths as the README writes them
            absolute = path.resolve()
            return str(absolute.relative_to(REPO_ROOT) if absolute.is_relative_to(REPO_ROOT)
                       else path)

        count = write_reference(outputs_bag, arguments.write_reference,
                                f'scripts/demo.sh --bag {shown(arguments.bag)} '
                                f'--write-reference {shown(arguments.write_reference)}')
        print(f'wrote {count} best points and decisions into {arguments.write_reference}')
    if not results:
        print('no object was seen: did the bag play?', file=sys.stderr)
        return 1
    return 1 if failed or mismatched else 0


if __name__ == '__main__':
    sys.exit(main())
