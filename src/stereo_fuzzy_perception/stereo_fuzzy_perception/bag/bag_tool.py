"""bag: play, record and summarise rosbag2 MCAP bags without rosbag2 (like `ros2 bag`).

  bag info BAG
  bag play BAG [--rate R] [--loop] [--start-offset S] [--topics T ...] [--remap OLD:=NEW ...]
               [--clock [HZ]] [--wait-for-subscribers] [--wait-timeout S] [--delay S]
  bag record -o OUT (TOPIC ... | --all) [--max-messages N] [--duration S] [--compression C]

ROS arguments (`--ros-args ...`) go to rclpy, e.g. `--ros-args -r __node:=player2`.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from collections.abc import Sequence
from pathlib import Path

from stereo_fuzzy_perception.bag.bag_io import (
    COMPRESSIONS,
    BagError,
    format_info,
    parse_remaps,
    read_info,
)


def build_parser() -> argparse.ArgumentParser:
    """Return the parser of `bag` and its subcommands."""
    parser = argparse.ArgumentParser(
        prog='bag', description='Play, record and summarise rosbag2 MCAP bags.')
    commands = parser.add_subparsers(dest='command', required=True)

    info = commands.add_parser('info', help='print topics, types, counts, duration')
    info.add_argument('bag', type=Path, help='bag directory')

    play = commands.add_parser('play', help='publish a bag onto the ROS graph')
    play.add_argument('bag', type=Path, help='bag directory')
    play.add_argument('-r', '--rate', type=float, default=1.0,
                      help='speed relative to the recording')
    play.add_argument('-l', '--loop', action='store_true', help='play again and again')
    play.add_argument('--start-offset', type=float, default=0.0,
                      help='skip the first seconds of the bag [s]')
    play.add_argument('--topics', nargs='+', metavar='TOPIC', help='play only these topics')
    play.add_argument('--remap', nargs='+', default=[], metavar='OLD:=NEW',
                      help='publish a recorded topic under another name')
    play.add_argument('--clock', nargs='?', type=float, const=40.0, default=0.0, metavar='HZ',
                      help='publish /clock (rosgraph_msgs/Clock) at HZ (default 40)')
    play.add_argument('--wait-for-subscribers', action='store_true',
                      help='start once every played topic has a subscriber')
    play.add_argument('--wait-timeout', type=float, default=30.0,
                      help='fail if subscribers have not appeared after this long [s]')
    play.add_argument('-d', '--delay', type=float, default=0.5,
                      help='wait this long before the first message [s] (after the '
                           'subscribers, so that they have matched the publishers too)')

    record = commands.add_parser('record', help='record topics into a new bag')
    record.add_argument('-o', '--output', type=Path, required=True,
                        help='bag directory to create')
    record.add_argument('topics', nargs='*', metavar='TOPIC', help='topics to record')
    record.add_argument('-a', '--all', action='store_true',
                        help='record every topic (except /rosout, /parameter_events, hidden)')
    record.add_argument('--max-messages', type=int, help='stop after N messages in total')
    record.add_argument('--duration', type=float, help='stop after this long [s]')
    record.add_argument('--compression', choices=COMPRESSIONS, default='zstd',
                        help='MCAP chunk compression')
    return parser


def _run_info(args: argparse.Namespace) -> int:
    print(format_info(read_info(args.bag)))
    return 0


def _run_with_node(args: argparse.Namespace, ros_args: list[str]) -> int:
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    from stereo_fuzzy_perception.bag.bag_player import BagPlayer, PlayOptions, topic_selection
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
        if args.command == 'play':
            player = BagPlayer(node, PlayOptions(
                bag=args.bag, rate=args.rate, loop=args.loop, start_offset_s=args.start_offset,
                topics=topic_selection(args.topics), remaps=parse_remaps(args.remap),
                clock_hz=args.clock, wait_for_subscribers=args.wait_for_subscribers,
                wait_timeout_s=args.wait_timeout, settle_s=args.delay))
            for recorded, published in player.published_topics().items():
                node.get_logger().info(f'playing {recorded} on {published}')
            count = player.run(stopped)
            print(f'published {count} messages from {args.bag}')
        else:
            if not args.topics and not args.all:
                raise BagError('name the topics to record, or pass --all')
            recorder = BagRecorder(node, RecordOptions(
                output=args.output, topics=tuple(args.topics), all_topics=args.all,
                max_messages=args.max_messages, duration_s=args.duration,
                compression=args.compression))
            count = recorder.run(executor, stopped)
            print(f'recorded {count} messages into {args.output}')
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


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
