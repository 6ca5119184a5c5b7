"""Start ROS executables as child processes the way `ros2 launch` would, and stop them cleanly.

There is no `launch` / `launch_ros` in the PyPI distribution of Jazzy, so this is the small part
of it the demo and the system tests need: start an installed executable with `--ros-args`
(parameter files, overrides, remaps), keep its output in a log file, wait for conditions, and stop
everything with SIGINT in reverse order.

The chain's process sets come from the same description the launch files read
(src/stereo_fuzzy_perception/launch/chain_processes.yaml), so `launch_chain SET` here and
`ros2 launch stereo_fuzzy_perception SET.launch.py` on a full install start the same processes:

  launch_chain chain port:=/dev/ttyUSB0 params_file:=chain/demo_params.yaml
  python -m chain.processes chain_without_hardware --log-dir /tmp/logs
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from stereo_fuzzy_perception.bringup.chain_description import (
    DESCRIPTION_FILE,
    ChainDescriptionError,
    ProcessSet,
    ProcessSpec,
    load_description,
    ros_arguments,
)
from stereo_fuzzy_perception.nodes.topic_names import (
    CAMERA_TOPICS,
    STEREO_NAMESPACE,
    in_namespace,
)

REPO_ROOT = Path(__file__).resolve().parents[1]
INSTALL_DIR = REPO_ROOT / 'ros2_ws' / 'install'
DESCRIPTION_PATH = REPO_ROOT / 'src' / 'stereo_fuzzy_perception' / 'launch' / DESCRIPTION_FILE
ERROR_LINE = re.compile(r'^\[(ERROR|FATAL)\]', re.MULTILINE)


def executable_path(package: str, executable: str) -> Path:
    """Return where colcon installs `executable` of `package` (what `ros2 run` starts)."""
    return INSTALL_DIR / package / 'lib' / package / executable


def source_share_directory(package: str) -> Path:
    """Return a package's folder in this repository: what colcon installs as its share/."""
    return REPO_ROOT / 'src' / package


def camera_remaps(namespace: str = STEREO_NAMESPACE) -> list[str]:
    """Return `bag play --remap` rules moving root camera topics into the camera namespace.

    The committed bags hold /left/image_raw, /left/camera_info, /right/image_raw and
    /right/camera_info; the chain description starts stereo_sync_node in `namespace`.
    """
    return [f'/{topic}:={in_namespace(namespace, topic)}' for topic in CAMERA_TOPICS]


def process_set(name: str, description: Path = DESCRIPTION_PATH) -> ProcessSet:
    """Return the process set `name` of the chain description (what `<name>.launch.py` starts).

    Raises:
        ChainDescriptionError: When the description has no such set or is malformed.
    """
    return load_description(description).process_set(name)


@dataclass
class ManagedProcess:
    """One started executable and its log file."""

    name: str
    process: subprocess.Popen[bytes]
    log_path: Path
    one_shot: bool = False  # expected to finish by itself (a bag player), not a failure

    def output(self) -> str:
        """Return what the process printed so far."""
        return self.log_path.read_text(errors='replace') if self.log_path.exists() else ''

    def running(self) -> bool:
        """Return True while the process has not exited."""
        return self.process.poll() is None

    def error_lines(self) -> list[str]:
        """Return the lines the process logged at ERROR or FATAL severity."""
        return [line for line in self.output().splitlines() if ERROR_LINE.match(line)]

    def stop(self, timeout: float = 15.0) -> int:
        """Interrupt the process (Ctrl-C), kill it if it does not exit, return its exit code."""
        if self.running():
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(timeout)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        return int(self.process.returncode)


@dataclass
class ProcessGroup:
    """Processes started together and stopped together, in reverse order."""

    log_dir: Path
    env: dict[str, str] = field(default_factory=lambda: dict(os.environ))
    processes: list[ManagedProcess] = field(default_factory=list)

    def start(self, name: str, command: Sequence[str | Path],
              one_shot: bool = False) -> ManagedProcess:
        """Start `command`, its output going to `<log_dir>/<name>.log`.

        A `one_shot` process is expected to exit by itself; its exit is not a failure.
        """
        self.log_dir.mkdir(parents=True, exist_ok=True)
        log_path = self.log_dir / f'{name}.log'
        env = dict(self.env, PYTHONUNBUFFERED='1', RCUTILS_COLORIZED_OUTPUT='0')
        with open(log_path, 'wb') as log:
            process = subprocess.Popen([str(part) for part in command], stdout=log,
                                       stderr=subprocess.STDOUT, env=env)
        managed = ManagedProcess(name, process, log_path, one_shot)
        self.processes.append(managed)
        return managed

    def start_node(self, package: str, executable: str, *ros_arguments: str | Path,
                   name: str | None = None) -> ManagedProcess:
        """Start an installed node with `--ros-args` followed by `ros_arguments`."""
        path = executable_path(package, executable)
        if not path.exists():
            raise FileNotFoundError(f'{path} is not installed: run scripts/setup.sh')
        return self.start(name or executable, [path, '--ros-args', *ros_arguments])

    def start_described(self, process: ProcessSpec, arguments: Mapping[str, str],
                        *extra_ros_arguments: str | Path) -> ManagedProcess:
        """Start a process of the chain description as the launch files start it, plus
        `extra_ros_arguments` (e.g. '-p', 'name:=value') after the described ones."""
        path = executable_path(process.package, process.executable)
        if not path.exists():
            raise FileNotFoundError(f'{path} is not installed: run scripts/setup.sh')
        return self.start(process.name, [
            path, *ros_arguments(process, arguments, source_share_directory),
            *extra_ros_arguments])

    def start_set(self, processes: ProcessSet, given: Mapping[str, str] | None = None,
                  extra: Mapping[str, Sequence[str | Path]] | None = None,
                  ) -> list[ManagedProcess]:
        """Start every process of a set in order, with the set's arguments (`given` over the
        defaults) and, per process name, extra ROS arguments."""
        arguments = processes.argument_values(given)
        return [self.start_described(process, arguments, *(extra or {}).get(process.name, ()))
                for process in processes.processes]

    def exited(self) -> list[ManagedProcess]:
        """Return the long-running processes that have already exited."""
        return [process for process in self.processes
                if not process.one_shot and not process.running()]

    def stop_all(self) -> dict[str, int]:
        """Stop every process, newest first; return their exit codes by name."""
        return {process.name: process.stop() for process in reversed(self.processes)}


def wait_for(predicate: Callable[[], bool], timeout: float, what: str,
             spin: Callable[[float], None] | None = None,
             watch: ProcessGroup | None = None) -> None:
    """Wait until `predicate()` holds, spinning ROS callbacks meanwhile.

    Args:
        predicate: The condition.
        timeout: Seconds before giving up [s].
        what: The condition in words, for the error.
        spin: Called with a short timeout [s] between checks (e.g. executor.spin_once).
        watch: A process group that must keep running; a process exiting fails the wait.

    Raises:
        TimeoutError: When the condition did not hold in time.
        RuntimeError: When a watched process exited.
    """
    deadline = time.monotonic() + timeout
    while not predicate():
        if watch is not None and watch.exited():
            gone = watch.exited()[0]
            raise RuntimeError(f'{gone.name} exited with {gone.process.returncode} while '
                               f'waiting for {what}; its log:\n{gone.output()[-3000:]}')
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            raise TimeoutError(f'timed out after {timeout:.0f} s waiting for {what}')
        if spin is not None:
            spin(min(0.05, remaining))
        else:
            time.sleep(min(0.05, remaining))


def main(argv: Sequence[str] | None = None) -> int:
    """Start a process set of the chain description and keep it running until Ctrl-C.

    Returns 0 when stopped by a signal, 1 when a process exited by itself (its log's end is
    printed) or the set could not be started.
    """
    try:
        description = load_description(DESCRIPTION_PATH)
    except ChainDescriptionError as error:
        print(f'launch_chain: {error}', file=sys.stderr)
        return 1
    parser = argparse.ArgumentParser(
        prog='launch_chain',
        description='Start a process set of the chain, as ros2 launch stereo_fuzzy_perception '
                    '<SET>.launch.py does on a full ROS 2 install.')
    parser.add_argument('set', choices=sorted(description.sets), help='the process set')
    parser.add_argument('arguments', nargs='*', metavar='NAME:=VALUE',
                        help='launch arguments: ' + ', '.join(
                            f'{a.name} ({a.description})' for a in description.arguments.values()))
    parser.add_argument('--log-dir', type=Path,
                        help='one log file per process (default: output/launch_chain/<SET>)')
    args = parser.parse_args(argv)
    given = {}
    for item in args.arguments:
        name, separator, value = item.partition(':=')
        if not separator:
            parser.error(f'argument {item!r} is not of the form NAME:=VALUE')
        given[name] = value
    log_dir = args.log_dir or REPO_ROOT / 'output' / 'launch_chain' / args.set
    group = ProcessGroup(log_dir)
    stop_requested: list[int] = []
    for signal_number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signal_number, lambda number, _frame: stop_requested.append(number))
    try:
        started = group.start_set(description.process_set(args.set), given)
    except (ChainDescriptionError, FileNotFoundError) as error:
        group.stop_all()
        print(f'launch_chain: {error}', file=sys.stderr)
        return 1
    for process in started:
        print(f'[launch_chain] started {process.name} (pid {process.process.pid}), log '
              f'{process.log_path}', flush=True)
    code = 0
    while not stop_requested:
        gone = group.exited()
        if gone:
            print(f'[launch_chain] {gone[0].name} exited with {gone[0].process.returncode}; '
                  f'the end of its log:\n{gone[0].output()[-2000:]}', file=sys.stderr)
            code = 1
            break
        time.sleep(0.2)
    codes = group.stop_all()
    print('[launch_chain] stopped: ' + ', '.join(f'{name} ({code})'
                                                  for name, code in codes.items()), flush=True)
    return code


if __name__ == '__main__':
    sys.exit(main())
