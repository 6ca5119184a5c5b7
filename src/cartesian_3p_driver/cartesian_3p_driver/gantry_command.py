"""gantry: command a running gantry_driver_node from a shell.

  gantry home            home the machine (std_srvs/Trigger gantry/home)
  gantry unlock          clear an alarm without homing (gantry/unlock)
  gantry stop            stop motion and drop queued moves (gantry/stop)
  gantry move X Y Z      move the tool to (X, Y, Z) in `world` [m] (MoveTo on gantry/move_to)
  gantry state           print the driver's latest gantry/state

Exit codes: 0 done, 1 the driver refused or the move failed, 2 bad arguments, 3 no driver
answered or the command did not finish in time. ROS arguments (`--ros-args -r __ns:=/rig2`)
go to rclpy, so the command reaches a driver in another namespace.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_USAGE = 2
EXIT_NO_ANSWER = 3

TRIGGERS = ('home', 'unlock', 'stop')
# How long each kind of command may take once the driver has it [s] (homing a large machine
# takes a minute or more).
DEFAULT_TIMEOUTS_S = {'home': 180.0, 'unlock': 30.0, 'stop': 30.0, 'move': 300.0, 'state': 0.0}


class NoAnswerError(RuntimeError):
    """The driver did not appear or did not answer in time."""


def build_parser() -> argparse.ArgumentParser:
    """Return the parser of `gantry`."""
    parser = argparse.ArgumentParser(
        prog='gantry', description='Command a running gantry_driver_node.',
        epilog='Exit codes: 0 done, 1 refused or failed, 2 bad arguments, 3 no driver '
               'answered in time.')
    parser.add_argument('--wait', type=float, default=10.0, metavar='S',
                        help='how long to wait for the driver to appear [s] (default 10)')
    parser.add_argument('--timeout', type=float, metavar='S',
                        help='how long the command may take once sent [s] (default: home 180, '
                             'unlock and stop 30, move 300)')
    commands = parser.add_subparsers(dest='command', required=True)
    commands.add_parser('home', help='home the machine (needed after power-up or an alarm)')
    commands.add_parser('unlock', help='clear an alarm without homing ($X)')
    commands.add_parser('stop', help='stop motion now and drop queued moves')
    move = commands.add_parser('move', help='move the tool to a point in world [m]')
    for axis in 'xyz':
        move.add_argument(axis, type=float, help=f'{axis.upper()} in world [m]')
    move.add_argument('--feed', type=float, default=0.0, metavar='MM_PER_MIN',
                      help="feed rate [mm/min] (default: the driver's)")
    commands.add_parser('state', help="print the driver's latest state")
    return parser


def format_point(point: Any) -> str:
    """Return a geometry_msgs Point as '(x, y, z) m' with millimetre resolution."""
    return f'({point.x:.4f}, {point.y:.4f}, {point.z:.4f}) m'


def format_state(state: Any) -> str:
    """Return the lines `gantry state` prints for a GantryState message."""
    lines = [
        f'state:            {state.state}{"" if state.sub_state < 0 else f":{state.sub_state}"}',
        f'connected:        {"yes" if state.connected else "no"}',
        f'homing required:  {"yes" if state.homing_required else "no"}',
        f'world position:   {format_point(state.world_position)}',
        f'machine position: {format_point(state.machine_position)}',
        f'lines sent/acked: {state.lines_sent}/{state.lines_acknowledged} '
        f'({state.lines_queued} queued)',
    ]
    if state.last_alarm_code:
        lines.append(f'last alarm:       ALARM:{state.last_alarm_code} {state.last_alarm_text}')
    if state.last_error_code:
        lines.append(f'last error:       error:{state.last_error_code} {state.last_error_text}')
    if state.last_rejection:
        lines.append(f'last rejection:   {state.last_rejection}')
    return '\n'.join(lines)


class GantryCommander:
    """The node and the waits behind each command."""

    def __init__(self, node: Any, executor: Any, wait_s: float,
                 interrupted: Callable[[], bool]) -> None:
        self.node = node
        self.executor = executor
        self.wait_s = wait_s
        self.interrupted = interrupted

    def _spin_until(self, condition: Callable[[], bool], timeout_s: float, what: str) -> None:
        deadline = time.monotonic() + timeout_s
        while not condition():
            if self.interrupted():
                raise KeyboardInterrupt
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                raise NoAnswerError(what)
            self.executor.spin_once(timeout_sec=min(0.05, remaining))

    def _pause(self, seconds: float) -> None:
        until = time.monotonic() + seconds
        while time.monotonic() < until:
            if self.interrupted():
                raise KeyboardInterrupt
            self.executor.spin_once(timeout_sec=0.05)

    def _resolved(self, name: str) -> str:
        return self.node.resolve_service_name(name)

    def _no_driver(self, name: str) -> str:
        return (f'no gantry driver answers on {name} (waited {self.wait_s:g} s): is '
                'gantry_driver_node running, with the same ROS_DOMAIN_ID and namespace?')

    def trigger(self, kind: str, timeout_s: float) -> tuple[int, str]:
        """Call gantry/<kind>; return (exit code, message)."""
        from std_srvs.srv import Trigger

        client = self.node.create_client(Trigger, f'gantry/{kind}')
        name = self._resolved(f'gantry/{kind}')
        try:
            self._spin_until(client.service_is_ready, self.wait_s, self._no_driver(name))
        except NoAnswerError as error:
            return EXIT_NO_ANSWER, str(error)
        # A driver that has just started may not have opened its link yet: within the wait
        # for the driver, a refusal for that reason is asked again.
        link_deadline = time.monotonic() + self.wait_s
        while True:
            future = client.call_async(Trigger.Request())
            try:
                self._spin_until(future.done, timeout_s,
                                 f'{name} did not answer within {timeout_s:g} s')
            except NoAnswerError as error:
                return EXIT_NO_ANSWER, str(error)
            response = future.result()
            if response.success or 'not connected' not in response.message or (
                    time.monotonic() >= link_deadline):
                break
            self._pause(0.5)
        verdict = 'done' if response.success else 'refused'
        return (EXIT_OK if response.success else EXIT_FAILED), f'{kind} {verdict}: ' + (
            response.message or '(no message)')

    def move(self, x: float, y: float, z: float, feed: float,
             timeout_s: float, progress: Callable[[str], None]) -> tuple[int, str]:
        """Send a MoveTo goal and wait for its result; return (exit code, message)."""
        from action_msgs.msg import GoalStatus
        from rclpy.action import ActionClient

        from stereo_fuzzy_msgs.action import MoveTo

        client = ActionClient(self.node, MoveTo, 'gantry/move_to')
        name = self._resolved('gantry/move_to')
        try:
            self._spin_until(client.server_is_ready, self.wait_s, self._no_driver(name))
        except NoAnswerError as error:
            return EXIT_NO_ANSWER, str(error)
        goal = MoveTo.Goal()
        goal.target.header.frame_id = 'world'
        goal.target.header.stamp = self.node.get_clock().now().to_msg()
        goal.target.point.x, goal.target.point.y, goal.target.point.z = x, y, z
        goal.feed_rate_mm_min = feed

        def on_feedback(message: Any) -> None:
            feedback = message.feedback
            progress(f'{feedback.state} at {format_point(feedback.current_position)}, '
                     f'{feedback.distance_remaining * 1000:.1f} mm to go')

        sent = client.send_goal_async(goal, feedback_callback=on_feedback)
        try:
            self._spin_until(sent.done, self.wait_s, f'{name} did not accept the goal in time')
        except NoAnswerError as error:
            return EXIT_NO_ANSWER, str(error)
        handle = sent.result()
        if not handle.accepted:
            return EXIT_FAILED, 'move refused: the driver rejected the goal'
        result_future = handle.get_result_async()
        try:
            self._spin_until(result_future.done, timeout_s,
                             f'the move did not finish within {timeout_s:g} s')
        except (NoAnswerError, KeyboardInterrupt) as error:
            cancel = handle.cancel_goal_async()
            deadline = time.monotonic() + 5.0
            while not cancel.done() and time.monotonic() < deadline:
                self.executor.spin_once(timeout_sec=0.05)
            if isinstance(error, KeyboardInterrupt):
                return EXIT_FAILED, 'move cancelled (interrupted)'
            return EXIT_NO_ANSWER, f'{error}; cancelled it'
        wrapped = result_future.result()
        result = wrapped.result
        position = format_point(result.final_position)
        if wrapped.status == GoalStatus.STATUS_SUCCEEDED and result.success:
            return EXIT_OK, f'move {result.outcome or "reached"}: tool at {position}'
        outcome = result.outcome or 'no reason given'
        return EXIT_FAILED, f'move failed: {outcome}; tool at {position}'

    def state(self) -> tuple[int, str]:
        """Wait for the driver's latched gantry/state; return (exit code, the state)."""
        from cartesian_3p_driver import qos
        from stereo_fuzzy_msgs.msg import GantryState

        received: list[Any] = []
        self.node.create_subscription(GantryState, 'gantry/state', received.append,
                                      qos.DRIVER_STATE)
        name = self.node.resolve_topic_name('gantry/state')
        try:
            self._spin_until(lambda: bool(received), self.wait_s,
                             f'no gantry driver publishes {name} (waited {self.wait_s:g} s): '
                             'is gantry_driver_node running, with the same ROS_DOMAIN_ID and '
                             'namespace?')
        except NoAnswerError as error:
            return EXIT_NO_ANSWER, str(error)
        return EXIT_OK, format_state(received[-1])


def run(args: argparse.Namespace, ros_args: list[str]) -> int:
    """Run one command on a fresh node; print its outcome; return the exit code."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    interrupted = False

    def on_signal(*_: object) -> None:
        nonlocal interrupted
        interrupted = True

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    rclpy.init(args=ros_args, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('gantry_command')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    commander = GantryCommander(node, executor, args.wait, lambda: interrupted)
    timeout = args.timeout if args.timeout is not None else DEFAULT_TIMEOUTS_S[args.command]
    last_progress = [0.0]

    def progress(text: str) -> None:
        now = time.monotonic()
        if sys.stderr.isatty():
            print(f'\r\033[K{text}', end='', file=sys.stderr, flush=True)
        elif now - last_progress[0] >= 1.0:
            print(text, file=sys.stderr, flush=True)
        else:
            return
        last_progress[0] = now

    try:
        if args.command in TRIGGERS:
            code, message = commander.trigger(args.command, timeout)
        elif args.command == 'move':
            code, message = commander.move(args.x, args.y, args.z, args.feed, timeout, progress)
            if sys.stderr.isatty():
                print(file=sys.stderr)
        else:
            code, message = commander.state()
    except KeyboardInterrupt:
        code, message = EXIT_FAILED, f'{args.command} interrupted'
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    print(message, file=sys.stdout if code == EXIT_OK else sys.stderr)
    return code


def main(argv: Sequence[str] | None = None) -> int:
    """Run `gantry <command>`; return the exit code."""
    arguments = list(sys.argv[1:] if argv is None else argv)
    ros_args = ['gantry']
    if '--ros-args' in arguments:
        split = arguments.index('--ros-args')
        arguments, ros_args = arguments[:split], ['gantry', *arguments[split:]]
    args = build_parser().parse_args(arguments)
    values = [args.wait] + ([args.timeout] if args.timeout is not None else [])
    if args.command == 'move':
        values += [args.x, args.y, args.z, args.feed]
    if not all(math.isfinite(value) for value in values) or args.wait < 0 or (
            args.timeout is not None and args.timeout <= 0) or (
            args.command == 'move' and args.feed < 0):
        print('gantry: --wait must be >= 0, --timeout > 0, coordinates finite and --feed >= 0',
              file=sys.stderr)
        return EXIT_USAGE
    return run(args, ros_args)


if __name__ == '__main__':
    sys.exit(main())
