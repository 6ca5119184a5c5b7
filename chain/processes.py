"""Start ROS executables as child processes the way `ros2 launch` would, and stop them cleanly.

There is no `launch` / `launch_ros` in the PyPI distribution of Jazzy, so this is the small part
of it the demo and the system tests need: start an installed executable with `--ros-args`
(parameter files, overrides, remaps), keep its output in a log file, wait for conditions, and stop
everything with SIGINT in reverse order.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
INSTALL_DIR = REPO_ROOT / 'ros2_ws' / 'install'
ERROR_LINE = re.compile(r'^\[(ERROR|FATAL)\]', re.MULTILINE)


def executable_path(package: str, executable: str) -> Path:
    """Return where colcon installs `executable` of `package` (what `ros2 run` starts)."""
    return INSTALL_DIR / package / 'lib' / package / executable


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
