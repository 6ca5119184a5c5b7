"""In-process harness for gantry driver tests: a simulator (no ROS), the driver node, a client.

The simulator runs ROS-free (GrblSimulator on a pty, its own thread); the driver node and a
client node share one executor that the test spins while it waits on conditions.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from cartesian_3p_driver.grbl_controller import ControllerSettings, FaultInjection, GrblController
from cartesian_3p_driver.grbl_simulator import GrblSimulator, SimulatorOptions
from ros_waiting import wait_until

#: Simulated seconds per wall second in the tests: a 20 s move takes 0.1 s.
TIME_SCALE = 200.0
TIMEOUT_S = 20.0


def start_simulator(tmp_path: Path, homing: bool = False, faults: FaultInjection | None = None,
                    settings: ControllerSettings | None = None,
                    work_offset_mm: tuple[float, float, float] = (0.0, 0.0, 0.0),
                    **options: Any) -> GrblSimulator:
    """Start a simulated Grbl on a pty linked at tmp_path/gantry_tty, logging received lines."""
    settings = settings or ControllerSettings(homing_enabled=homing)
    controller = GrblController(settings, faults or FaultInjection(),
                                work_offset_mm=work_offset_mm)
    sim_options = SimulatorOptions(link_path=str(tmp_path / 'gantry_tty'),
                                   time_scale=options.pop('time_scale', TIME_SCALE),
                                   received_lines_log=str(tmp_path / 'received.log'), **options)
    simulator = GrblSimulator(controller, sim_options)
    simulator.start()
    return simulator


@dataclass
class GantryClient:
    """The driver node, a client node and their executor, for one test."""

    context: Any
    tmp_path: Path
    overrides: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        import rclpy
        from cartesian_3p_driver.gantry_driver_node import GantryDriverNode
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import PointStamped
        from rclpy.action import ActionClient
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.parameter import Parameter
        from sensor_msgs.msg import JointState
        from std_srvs.srv import Trigger

        from cartesian_3p_driver import qos
        from stereo_fuzzy_msgs.action import MoveTo
        from stereo_fuzzy_msgs.msg import GantryState

        parameters = {
            'port': str(self.tmp_path / 'gantry_tty'),
            'sent_lines_log': str(self.tmp_path / 'sent.log'),
            'poll_rate_hz': 5.0,
            'reconnect_initial_s': 0.1,
            'reconnect_max_s': 0.5,
            'banner_timeout_s': 1.0,
        }
        parameters.update(self.overrides)
        self.driver = GantryDriverNode(
            context=self.context,
            parameter_overrides=[Parameter(name, value=value)
                                 for name, value in parameters.items()])
        self.node = rclpy.create_node('gantry_test_client', context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.driver)
        self.executor.add_node(self.node)
        self.states: list[GantryState] = []
        self.joints: list[JointState] = []
        self.diagnostics: list[DiagnosticArray] = []
        self.feedback: list[Any] = []
        self.node.create_subscription(GantryState, 'gantry/state', self.states.append,
                                      qos.DRIVER_STATE)
        self.node.create_subscription(JointState, 'joint_states', self.joints.append, 10)
        self.node.create_subscription(DiagnosticArray, '/diagnostics',
                                      self.diagnostics.append, 10)
        self.best_point = self.node.create_publisher(PointStamped, 'best_point', 10)
        self.move_to = ActionClient(self.node, MoveTo, 'gantry/move_to')
        self.services = {name: self.node.create_client(Trigger, f'gantry/{name}')
                         for name in ('home', 'unlock', 'stop')}

    # -- waiting ------------------------------------------------------------------------------

    def wait(self, predicate: Any, what: str, timeout: float = TIMEOUT_S) -> None:
        wait_until(predicate, timeout, what, self.executor, poll=0.01)

    @property
    def state(self) -> Any:
        return self.states[-1] if self.states else None

    def wait_state(self, predicate: Any, what: str, timeout: float = TIMEOUT_S) -> Any:
        self.wait(lambda: self.state is not None and predicate(self.state),
                  f'gantry/state with {what} (last: {self.describe()})', timeout)
        return self.state

    def describe(self) -> str:
        state = self.state
        if state is None:
            return 'none'
        return (f'{state.state}:{state.sub_state} connected={state.connected} '
                f'homing_required={state.homing_required} '
                f'error={state.last_error_code} alarm={state.last_alarm_code} '
                f'rejection={state.last_rejection!r} at {state.world_position}')

    def wait_ready(self) -> Any:
        return self.wait_state(lambda s: s.connected and s.state == 'Idle', 'connected and Idle')

    # -- requests -----------------------------------------------------------------------------

    def call(self, name: str, timeout: float = TIMEOUT_S) -> Any:
        from std_srvs.srv import Trigger

        client = self.services[name]
        self.wait(client.service_is_ready, f'gantry/{name} service')
        future = client.call_async(Trigger.Request())
        self.wait(future.done, f'gantry/{name} response', timeout)
        return future.result()

    def publish_target(self, x: float, y: float, z: float, frame_id: str = 'world',
                       age_s: float = 0.0, stamped: bool = True) -> None:
        from geometry_msgs.msg import PointStamped
        from rclpy.duration import Duration

        msg = PointStamped()
        msg.header.frame_id = frame_id
        if stamped:
            stamp = self.node.get_clock().now() - Duration(seconds=age_s)
            msg.header.stamp = stamp.to_msg()
        msg.point.x, msg.point.y, msg.point.z = x, y, z
        self.wait(lambda: self.best_point.get_subscription_count() > 0,
                  'the driver subscribing to best_point')
        self.best_point.publish(msg)

    def send_goal(self, x: float, y: float, z: float, feed: float = 0.0,
                  frame_id: str = 'world') -> Any:
        from stereo_fuzzy_msgs.action import MoveTo

        self.wait(lambda: self.move_to.server_is_ready(), 'the gantry/move_to action server')
        goal = MoveTo.Goal()
        goal.target.header.frame_id = frame_id
        goal.target.header.stamp = self.node.get_clock().now().to_msg()
        goal.target.point.x, goal.target.point.y, goal.target.point.z = x, y, z
        goal.feed_rate_mm_min = feed
        future = self.move_to.send_goal_async(goal, feedback_callback=self.feedback.append)
        self.wait(future.done, 'goal acceptance')
        return future.result()

    def result_of(self, goal_handle: Any, timeout: float = TIMEOUT_S) -> Any:
        future = goal_handle.get_result_async()
        self.wait(future.done, 'the move result', timeout)
        return future.result().result

    # -- logs ---------------------------------------------------------------------------------

    def sent_lines(self) -> list[str]:
        path = self.tmp_path / 'sent.log'
        return path.read_text().splitlines() if path.exists() else []

    def received_lines(self) -> list[str]:
        path = self.tmp_path / 'received.log'
        return path.read_text().splitlines() if path.exists() else []

    def close(self) -> None:
        self.move_to.destroy()
        self.driver.destroy_node()
        self.node.destroy_node()
        self.executor.shutdown()


def at(point: Any, x: float, y: float, z: float, tolerance: float = 1e-4) -> bool:
    """True when a geometry_msgs Point is within `tolerance` [m] of (x, y, z)."""
    return math.dist((point.x, point.y, point.z), (x, y, z)) <= tolerance


@pytest.fixture
def gantry(ros_context: Any, tmp_path: Path) -> Iterator[Any]:
    """Factory: start a simulator and a driver (with parameter overrides) for one test."""
    started: list[tuple[GrblSimulator, GantryClient]] = []

    def start(overrides: dict[str, Any] | None = None, **simulator_options: Any
              ) -> tuple[GrblSimulator, GantryClient]:
        simulator = start_simulator(tmp_path, **simulator_options)
        client = GantryClient(ros_context, tmp_path, overrides or {})
        started.append((simulator, client))
        return simulator, client

    yield start
    for simulator, client in started:
        client.close()
        simulator.stop()
