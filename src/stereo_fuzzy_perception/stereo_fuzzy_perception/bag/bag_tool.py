"""bag: play, record and summarise rosbag2 MCAP bags without rosbag2 (like `ros2 bag`).

  bag info BAG
  bag play BAG [--rate R] [--loop] [--start-offset S] [--playback-duration S]
               [--topics T ...] [--regex RE] [--exclude-topics T ...] [--exclude-regex RE]
               [--remap OLD:=NEW ...] [--qos-profile-overrides-path FILE] [--clock [HZ]]
               [--start-paused] [--wait-for-subscribers] [--wait-timeout S] [--delay S]
  bag record [-o OUT] (TOPIC ... | --all | --regex RE) [--exclude-topics T ...]
             [--exclude-regex RE] [--qos-profile-overrides-path FILE] [--max-messages N]
             [--duration S] [--max-bag-size BYTES] [--max-bag-duration S] [--compression C]

BAG is a rosbag2 MCAP directory or a single .mcap file. ROS arguments (`--ros-args ...`) go to
rclpy, e.g. `--ros-args -r __node:=player2`.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import signal
import sys
import threading
from collections.abc import Sequence
from pathlib import Path

from stereo_fuzzy_perception.bag.bag_format import BagError
from stereo_fuzzy_perception.bag.bag_reader import read_info
from stereo_fuzzy_perception.bag.bag_summary import format_info
from stereo_fuzzy_perception.bag.bag_writer import COMPRESSIONS
from stereo_fuzzy_perception.bag.topic_selection import parse_remaps


def build_parser() -> argparse.ArgumentParser:
    """Return the parser of `bag` and its subcommands."""
    parser = argparse.ArgumentParser(
        prog='bag', description='Play, record and summarise rosbag2 MCAP bags.')
    commands = parser.add_subparsers(dest='command', required=True)

    info = commands.add_parser('info', help='print topics, types, counts, duration, custom data')
    info.add_argument('bag', type=Path, help='bag directory or .mcap file')

    play = commands.add_parser('play', help='publish a bag onto the ROS graph')
    play.add_argument('bag', type=Path, help='bag directory or .mcap file')
    play.add_argument('-r', '--rate', type=float, default=1.0,
                      help='speed relative to the recording')
    play.add_argument('-l', '--loop', action='store_true', help='play again and again')
    play.add_argument('--start-offset', type=float, default=0.0,
                      help='skip the first seconds of the bag [s]')
    play.add_argument('--playback-duration', type=float, metavar='S',
                      help='play only this much bag time [s]')
    _add_selection(play, 'play')
    play.add_argument('--remap', '-m', nargs='+', default=[], metavar='OLD:=NEW',
                      help='publish a recorded topic under another name')
    play.add_argument('--clock', nargs='?', type=float, const=40.0, default=0.0, metavar='HZ',
                      help='publish /clock (rosgraph_msgs/Clock) at HZ (default 40)')
    play.add_argument('-p', '--start-paused', action='store_true',
                      help='start paused; resume or step with the services '
                           '~/resume, ~/play_next (std_srvs/Trigger)')
    play.add_argument('--wait-for-subscribers', action='store_true',
                      help='start once every played topic has a subscriber')
    play.add_argument('--wait-timeout', type=float, default=30.0,
                      help='fail if subscribers have not appeared after this long [s]')
    play.add_argument('-d', '--delay', type=float, default=0.5,
                      help='wait this long before the first message [s] (after the '
                           'subscribers, so that they have matched the publishers too)')
    play.add_argument('--progress', choices=('auto', 'always', 'never'), default='auto',
                      help='a progress line (auto: when the output is a terminal)')

    record = commands.add_parser('record', help='record topics into a new bag')
    record.add_argument('-o', '--output', type=Path,
                        help='bag directory to create (default rosbag2_YYYY_MM_DD-HH_MM_SS)')
    record.add_argument('topics', nargs='*', metavar='TOPIC', help='topics to record')
    record.add_argument('-a', '--all', action='store_true',
                        help='record every topic (except /rosout, /parameter_events, hidden)')
    _add_selection(record, 'record', topics=False)
    record.add_argument('--max-messages', type=int, help='stop after N messages in total')
    record.add_argument('--duration', type=float, help='stop after this long [s]')
    record.add_argument('-b', '--max-bag-size', type=int, default=0, metavar='BYTES',
                        help='split into files of about this size (0: one file)')
    record.add_argument('--max-bag-duration', type=float, default=0.0, metavar='S',
                        help='split into files of this much time [s] (0: one file)')
    record.add_argument('--compression', choices=COMPRESSIONS, default='zstd',
                        help='MCAP chunk compression')
    return parser


def _add_selection(parser: argparse.ArgumentParser, verb: str, topics: bool = True) -> None:
    if topics:
        parser.add_argument('--topics', nargs='+', metavar='TOPIC', help=f'{verb} these topics')
    parser.add_argument('-e', '--regex', metavar='RE',
                        help=f'{verb} the topics matching this regular expression')
    parser.add_argument('--exclude-topics', nargs='+', default=[], metavar='TOPIC',
                        help=f'do not {verb} these topics')
    parser.add_argument('-x', '--exclude-regex', metavar='RE',
                        help=f'do not {verb} the topics matching this regular expression')
    parser.add_argument('--qos-profile-overrides-path', type=Path, metavar='FILE',
                        help="QoS per topic, in rosbag2's override file format")


def default_output_name(now: datetime.datetime | None = None) -> Path:
    """Return rosbag2's default bag name for a recording started `now` (local time)."""
    return Path((now or datetime.datetime.now()).strftime('rosbag2_%Y_%m_%d-%H_%M_%S'))


class _ProgressLine:
    """A line rewritten in place on a terminal."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled
        self.shown = False

    def __call__(self, text: str) -> None:
        if self.enabled:
            sys.stdout.write(f'\r\033[K{text}')
            sys.stdout.flush()
            self.shown = True

    def end(self) -> None:
        if self.shown:
            sys.stdout.write('\n')
            self.shown = False


def _run_info(args: argparse.Namespace) -> int:
    print(format_info(read_info(args.bag)))
    return 0


def _run_with_node(args: argparse.Namespace, ros_args: list[str]) -> int:
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    from stereo_fuzzy_perception.bag.bag_player import BagPlayer, PlayOptions, topic_selection
    from stereo_fuzzy_perception.bag.bag_qos import load_qos_overrides
    from stereo_fuzzy_perception.bag.bag_recorder import BagRecorder, RecordOptions

    # Ctrl-C and SIGTERM only ask to stop: the player stops between messages, the recorder
    # handles what has already arrived and closes the bag, then the context shuts down.
    interrupted = threading.Event()
    for signal_number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signal_number, lambda *_: interrupted.set())
    rclpy.init(args=ros_args, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('bag_player' if args.command == 'play' else 'bag_recorder')
    executor = SingleThreadedExecutor()
    executor.add_node(node)

    def stopped() -> bool:
        return interrupted.is_set() or not rclpy.ok()

    try:
        overrides = ({} if args.qos_profile_overrides_path is None
                     else load_qos_overrides(args.qos_profile_overrides_path))
        if args.command == 'play':
            progress = _ProgressLine(args.progress == 'always' or (
                args.progress == 'auto' and sys.stdout.isatty()))
            player = BagPlayer(node, PlayOptions(
                bag=args.bag, rate=args.rate, loop=args.loop, start_offset_s=args.start_offset,
                topics=topic_selection(args.topics), regex=args.regex,
                exclude_topics=tuple(args.exclude_topics), exclude_regex=args.exclude_regex,
                remaps=parse_remaps(args.remap), qos_overrides=overrides,
                clock_hz=args.clock, wait_for_subscribers=args.wait_for_subscribers,
                wait_timeout_s=args.wait_timeout, settle_s=args.delay,
                start_paused=args.start_paused, duration_s=args.playback_duration),
                progress=progress)
            for recorded, published in player.published_topics().items():
                node.get_logger().info(f'playing {recorded} on {published}')
            if args.start_paused:
                node.get_logger().info(
                    f'paused: call {node.get_fully_qualified_name()}/resume or /play_next '
                    '(std_srvs/Trigger)')
            # The pause services are served from a thread; messages go out from this one.
            played = threading.Event()
            spinner = threading.Thread(target=_spin_until, args=(executor, played), daemon=True)
            spinner.start()
            try:
                count = player.run(stopped)
            finally:
                played.set()
                spinner.join()
                progress.end()
            print(f'published {count} messages from {args.bag}')
        else:
            if not args.topics and not args.all and args.regex is None:
                raise BagError('name the topics to record, or pass --all or --regex')
            output = args.output or default_output_name()
            recorder = BagRecorder(node, RecordOptions(
                output=output, topics=tuple(args.topics), all_topics=args.all,
                regex=args.regex, exclude_topics=tuple(args.exclude_topics),
                exclude_regex=args.exclude_regex, qos_overrides=overrides,
                max_messages=args.max_messages, duration_s=args.duration,
                compression=args.compression, max_bag_size=args.max_bag_size,
                max_bag_duration_s=args.max_bag_duration))
            count = recorder.run(executor, stopped)
            print(f'recorded {count} messages into {output}')
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


def _spin_until(executor: object, done: threading.Event) -> None:
    """Serve the player's services until `done` is set (or the context shuts down)."""
    from rclpy.executors import ExternalShutdownException

    with contextlib.suppress(ExternalShutdownException):
        while not done.is_set():
            executor.spin_once(timeout_sec=0.05)  # type: ignore[attr-defined]


def main(argv: Sequence[str] | None = None) -> int:
    """Run `bag <command>`; return the exit code (1 with a message on a bag error)."""
    arguments = list(sys.argv[1:] if argv is None else argv)
    if '--ros-args' in arguments:
        split = arguments.index('--ros-args')
        arguments, ros_args = arguments[:split], ['bag', *arguments[split:]]
    else:
        ros_args = ['bag']
    args = build_parser().parse_args(arguments)
    try:
        if args.command == 'info':
            return _run_info(args)
        return _run_with_node(args, ros_args)
    except (BagError, LookupError) as error:
        print(f'bag {args.command}: {error}', file=sys.stderr)
        return 1


if __name__ == '__main__':
    sys.exit(main())
