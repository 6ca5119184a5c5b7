"""Pytest fixtures for tests that use real rclpy over Fast DDS.

Every ROS test gets a ROS domain of its own, held by a file lock for the whole test, and
localhost-only discovery, so two test runs on one machine never see each other's topics.
"""

from __future__ import annotations

import os
import signal
import subprocess
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from ros_waiting import wait_until

from chain.ros_domains import NoFreeDomainError, reserved_domain_id

REPO_ROOT = Path(__file__).resolve().parents[2]
INSTALL_DIR = REPO_ROOT / 'ros2_ws' / 'install'


@pytest.fixture
def ros_domain_id(monkeypatch: pytest.MonkeyPatch) -> Iterator[int]:
    """Reserve a ROS domain id no other test on this machine holds, and export it."""
    try:
        with reserved_domain_id() as domain_id:
            monkeypatch.setenv('ROS_DOMAIN_ID', str(domain_id))
            monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
            yield domain_id
    except NoFreeDomainError as error:
        pytest.fail(str(error))


@pytest.fixture
def ros_context(ros_domain_id: int) -> Iterator[object]:
    """An initialised rclpy context of the test's own, shut down afterwards."""
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context, domain_id=ros_domain_id)
    try:
        yield context
    finally:
        context.try_shutdown()


@dataclass
class RosProcess:
    """An installed executable running as a child process, its output in a log file."""

    name: str
    process: subprocess.Popen[bytes]
    log_path: Path

    def output(self) -> str:
        """Return everything the process printed so far."""
        return self.log_path.read_text(errors='replace')

    def wait_for_exit(self, timeout: float) -> str:
        """Wait for the process to end on its own; return its output (fail if it still runs)."""
        try:
            self.process.wait(timeout)
        except subprocess.TimeoutExpired:
            pytest.fail(f'{self.name} still runs after {timeout} s:\n{self.output()}')
        return self.output()

    def interrupt(self, timeout: float = 15.0) -> int:
        """Send SIGINT as Ctrl-C would and return the exit code."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(timeout)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
                pytest.fail(f'{self.name} ignored SIGINT for {timeout} s:\n{self.output()}')
        return self.process.returncode


def executable_path(package: str, executable: str) -> Path:
    """Path where colcon installs `executable` of `package` (what `ros2 run` would start)."""
    return INSTALL_DIR / package / 'lib' / package / executable


@pytest.fixture
def start_ros_process(
    ros_domain_id: int, tmp_path: Path
) -> Iterator[Callable[..., RosProcess]]:
    """Start installed executables like `ros2 run`; interrupt any still running at the end."""
    started: list[RosProcess] = []

    def start(package: str, executable: str, *arguments: str,
              env: dict[str, str] | None = None) -> RosProcess:
        path = executable_path(package, executable)
        assert path.exists(), f'{path} is not installed: run scripts/setup.sh'
        log_path = tmp_path / f'{executable}-{len(started)}.log'
        process_env = dict(os.environ, PYTHONUNBUFFERED='1', RCUTILS_COLORIZED_OUTPUT='0')
        process_env.update(env or {})
        with open(log_path, 'wb') as log:
            process = subprocess.Popen(
                [str(path), *arguments], stdout=log, stderr=subprocess.STDOUT, env=process_env)
        ros_process = RosProcess(executable, process, log_path)
        started.append(ros_process)
        return ros_process

    yield start
    for ros_process in started:
        ros_process.interrupt()


__all__ = ['RosProcess', 'executable_path', 'wait_until']
