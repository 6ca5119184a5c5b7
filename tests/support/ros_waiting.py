"""Wait on conditions, never on fixed sleeps: spin an executor until a predicate holds."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any


def wait_until(
    predicate: Callable[[], bool],
    timeout: float,
    what: str,
    executor: Any | None = None,
    poll: float = 0.05,
) -> None:
    """Spin `executor` (or sleep briefly when there is none) until `predicate()` is true.

    Args:
        predicate: The condition to wait for.
        timeout: Seconds before giving up [s].
        what: What is being waited for, for the failure message.
        executor: An rclpy executor to spin while waiting, if callbacks must run.
        poll: Longest single wait between checks [s].

    Raises:
        AssertionError: When the condition did not hold within `timeout`.
    """
    deadline = time.monotonic() + timeout
    while not predicate():
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            raise AssertionError(f'timed out after {timeout} s waiting for {what}')
        if executor is not None:
            executor.spin_once(timeout_sec=min(poll, remaining))
        else:
            time.sleep(min(poll, remaining))


def wait_for_node(node: Any, name: str, timeout: float, executor: Any | None = None) -> None:
    """Wait until a node called `name` (without namespace) is on the ROS graph."""
    wait_until(lambda: name in node.get_node_names(), timeout,
               f'node {name!r} on the ROS graph', executor)
