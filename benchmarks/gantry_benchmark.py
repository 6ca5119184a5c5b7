"""Gantry driver benchmark against the simulated Grbl on a real pty.

1. Latency from publishing a `best_point` to the first G-code byte reaching the controller
   (the driver node in-process with real rclpy, the simulator in a thread of this process,
   both timed with the same clock).
2. Lines per second through send-response and character counting (LineStreamer over pyserial
   against the simulator), with no reply latency and with 2 ms per reply (like a USB link).

Run: source scripts/env.sh && python benchmarks/gantry_benchmark.py [--moves 30 --lines 2000]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO_ROOT / 'src' / 'cartesian_3p_driver'))

import serial  # noqa: E402
from cartesian_3p_driver.grbl_controller import (  # noqa: E402
    ControllerSettings,
    FaultInjection,
    GrblController,
)
from cartesian_3p_driver.grbl_protocol import ReplyKind, classify  # noqa: E402
from cartesian_3p_driver.grbl_simulator import GrblSimulator, SimulatorOptions  # noqa: E402
from cartesian_3p_driver.line_streamer import LineStreamer  # noqa: E402


def start_simulator(directory: Path, reply_delay_s: float = 0.0) -> GrblSimulator:
    controller = GrblController(ControllerSettings(homing_enabled=False), FaultInjection())
    simulator = GrblSimulator(controller, SimulatorOptions(
        link_path=str(directory / 'tty'), time_scale=1000.0, reply_delay_s=reply_delay_s))
    simulator.start()
    return simulator


def wait(predicate, timeout: float, what: str, spin=None) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise TimeoutError(f'timed out waiting for {what}')
        if spin is not None:
            spin(0.002)
        else:
            time.sleep(0.0005)


def best_point_latency(moves: int) -> list[float]:
    """Return the best_point -> first G-code byte latencies [s] of `moves` moves."""
    import rclpy
    from cartesian_3p_driver.gantry_driver_node import GantryDriverNode
    from geometry_msgs.msg import PointStamped
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    latencies = []
    with tempfile.TemporaryDirectory() as directory:
        simulator = start_simulator(Path(directory))
        first_byte_at: list[float] = []
        receive = simulator.controller.receive

        def timed_receive(data: bytes, now: float) -> None:
            if b'G53' in data:
                first_byte_at.append(time.perf_counter())
            receive(data, now)

        simulator.controller.receive = timed_receive  # type: ignore[method-assign]
        context = Context()
        rclpy.init(context=context, domain_id=99)
        driver = GantryDriverNode(context=context, parameter_overrides=[
            Parameter('port', value=str(Path(directory) / 'tty')),
            Parameter('max_target_age_s', value=0.0)])
        probe = rclpy.create_node('benchmark_probe', context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(driver)
        executor.add_node(probe)
        publisher = probe.create_publisher(PointStamped, 'best_point', 10)

        def spin(timeout: float) -> None:
            executor.spin_once(timeout_sec=timeout)

        try:
            wait(lambda: driver._snapshot.connected, 20.0, 'the driver to connect', spin)
            wait(lambda: publisher.get_subscription_count() > 0, 20.0, 'discovery', spin)
            for i in range(moves):
                x = 0.05 + 0.01 * (i % 20)
                msg = PointStamped()
                msg.header.frame_id = 'world'
                msg.point.x, msg.point.y, msg.point.z = x, 0.1, 0.0
                before = len(first_byte_at)
                published_at = time.perf_counter()
                publisher.publish(msg)
                wait(lambda b=before: len(first_byte_at) > b, 10.0, 'the first byte', spin)
                latencies.append(first_byte_at[before] - published_at)
                wait(lambda x=x: driver._snapshot.state == 'Idle'
                     and driver._snapshot.machine_position_mm is not None
                     and abs(driver._snapshot.machine_position_mm[0] - x * 1000) < 0.01,
                     20.0, 'Idle at the target', spin)
        finally:
            driver.destroy_node()
            probe.destroy_node()
            executor.shutdown()
            context.try_shutdown()
            simulator.stop()
    return latencies


def lines_per_second(mode: str, lines: int, reply_delay_s: float) -> float:
    """Stream `lines` modal lines in `mode`; return acknowledged lines per second."""
    with tempfile.TemporaryDirectory() as directory:
        simulator = start_simulator(Path(directory), reply_delay_s)
        port = serial.serial_for_url(str(Path(directory) / 'tty'), 115200, timeout=0.001)
        try:
            received = bytearray()

            def banner_seen() -> bool:
                received.extend(port.read(256))
                return b'Grbl' in received

            wait(banner_seen, 5.0, 'the banner')
            streamer = LineStreamer(port, mode)
            streamer.enqueue(['G21 G90 G94 F1000'] * lines)
            pending = b''
            started = time.perf_counter()
            while streamer.lines_acknowledged < lines:
                streamer.pump()
                pending += port.read(4096)
                *complete, pending = pending.split(b'\n')
                for raw in complete:
                    reply = classify(raw.decode('ascii', 'replace'))
                    if reply.kind in (ReplyKind.OK, ReplyKind.ERROR):
                        streamer.acknowledge()
            elapsed = time.perf_counter() - started
            assert simulator.received_lines == ['G21 G90 G94 F1000'] * lines
        finally:
            port.close()
            simulator.stop()
    return lines / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--moves', type=int, default=30)
    parser.add_argument('--lines', type=int, default=2000)
    arguments = parser.parse_args()

    latencies = sorted(best_point_latency(arguments.moves))
    p95 = latencies[min(len(latencies) - 1, int(0.95 * len(latencies)))]
    print(f'\nbest_point -> first G-code byte on the wire ({len(latencies)} moves)')
    print('| median [ms] | p95 [ms] | max [ms] |')
    print('|---|---|---|')
    print(f'| {statistics.median(latencies) * 1e3:.2f} | {p95 * 1e3:.2f} | '
          f'{latencies[-1] * 1e3:.2f} |')

    print(f'\nstreaming throughput ({arguments.lines} lines of 18 bytes, simulator on a pty)')
    print('| mode | reply latency 0 ms [lines/s] | reply latency 2 ms [lines/s] |')
    print('|---|---|---|')
    for mode in ('send_response', 'character_counting'):
        fast = lines_per_second(mode, arguments.lines, 0.0)
        slow = lines_per_second(mode, max(arguments.lines // 4, 100), 0.002)
        print(f'| {mode} | {fast:.0f} | {slow:.0f} |')


if __name__ == '__main__':
    main()
