"""run_node: how a node's process ends."""

import pytest
import rclpy
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

from stereo_fuzzy_parameters import declaration


class _Idle:
    def destroy_node(self):
        pass


def _spin_raising_after(shut_down):
    def spin(node):
        if shut_down:
            rclpy.shutdown()  # as rclpy's SIGINT handler does while spin runs
        raise _rclpy.RCLError('failed to initialize wait set: the given context is not valid')
    return spin


def test_a_wait_set_refused_after_shutdown_ends_the_node_normally(monkeypatch):
    monkeypatch.setattr(declaration.rclpy, 'spin', _spin_raising_after(shut_down=True))
    declaration.run_node(_Idle, args=[])  # returns: no exception, no exit code 1
    assert not rclpy.ok()


def test_an_rcl_error_while_the_context_is_valid_still_raises(monkeypatch):
    monkeypatch.setattr(declaration.rclpy, 'spin', _spin_raising_after(shut_down=False))
    with pytest.raises(_rclpy.RCLError):
        declaration.run_node(_Idle, args=[])
    assert not rclpy.ok()  # shut down on the way out all the same
