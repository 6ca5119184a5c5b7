"""Drive a Grbl-compatible 3-axis gantry from best points over a serial line.

A thin adapter around GrblLink (grbl_link.py), the serial runner of the sans-I/O
GrblSession (grbl_session.py). Threading: the serial port belongs to the
link's own I/O thread, so a slow or dead controller never blocks this node's executor. The
link hands events back through a thread-safe queue and a guard condition; the guard
condition's callback runs in the executor, which is the only thread that publishes, completes
action goals and answers services. Service and action callbacks are coroutines awaiting
rclpy futures, so a long homing cycle does not hold the (single-threaded) executor either.
All callbacks share one reentrant callback group: a pending coroutine in a mutually exclusive
group would keep the guard condition that completes it from ever running (a deadlock).
"""

from __future__ import annotations

import queue
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.task import Future
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from stereo_fuzzy_parameters.declaration import declare_settings, run_node

from stereo_fuzzy_msgs.action import MoveTo
from stereo_fuzzy_msgs.msg import GantryState

from . import qos
from .conversions import (
    target_from_point_stamped,
    to_diagnostics,
    to_feedback,
    to_gantry_state,
    to_joint_state,
    to_result,
)
from .gantry_driver_parameters import GantryDriverSettings
from .gcode import (
    TargetRejectedError,
    Vector3,
    check_feed,
    check_target,
    plan_move,
)
from .grbl_link import GrblLink, LinkConfig
from .link_events import (
    GantrySnapshot,
    LinkEvent,
    MoveFeedback,
    MoveFinished,
    RequestFinished,
    SessionConfig,
)


def link_config_from(settings: GantryDriverSettings) -> LinkConfig:
    """Build the serial link configuration from the node's settings."""
    session = SessionConfig(
        streaming_mode=settings.streaming_mode, poll_period_s=1.0 / settings.poll_rate_hz,
        banner_timeout_s=settings.banner_timeout_s, reply_timeout_s=settings.reply_timeout_s,
        homing_timeout_s=settings.homing_timeout_s, link_timeout_s=settings.link_timeout_s,
        stop_timeout_s=settings.stop_timeout_s, new_target_policy=settings.new_target_policy,
        max_queued_moves=settings.max_queued_moves,
        position_tolerance_mm=settings.position_tolerance_mm,
        require_homing_at_start=settings.require_homing_at_start,
    )
    return LinkConfig(
        port=settings.port, baud=settings.baud,
        reconnect_initial_s=settings.reconnect_initial_s,
        reconnect_max_s=settings.reconnect_max_s,
        sent_lines_log=settings.sent_lines_log, session=session,
    )


class GantryDriverNode(Node):
    """Drive a Grbl-compatible 3-axis gantry from best points over a serial line."""

    def __init__(self, **node_options: Any) -> None:
        super().__init__('gantry_driver_node', **node_options)
        self.settings = declare_settings(self, GantryDriverSettings, apply=self._apply_settings)
        settings = self.settings
        self._motion = settings.motion_config()
        self._snapshot = GantrySnapshot(port=settings.port)
        self._last_rejection = ''
        self._events: queue.SimpleQueue[LinkEvent] = queue.SimpleQueue()
        self._move_futures: dict[int, Future] = {}
        self._goal_handles: dict[int, ServerGoalHandle] = {}
        self._request_futures: dict[int, Future] = {}

        self._state_pub = self.create_publisher(GantryState, 'gantry/state', qos.DRIVER_STATE)
        self._joint_pub = self.create_publisher(JointState, 'joint_states', qos.JOINT_STATES)
        self._diagnostics_pub = self.create_publisher(DiagnosticArray, '/diagnostics',
                                                      qos.DIAGNOSTICS)
        group = ReentrantCallbackGroup()
        self.create_subscription(PointStamped, 'best_point', self._on_best_point, qos.COMMANDS,
                                 callback_group=group)
        for kind in ('home', 'unlock', 'stop'):
            self.create_service(Trigger, f'gantry/{kind}', self._make_request_callback(kind),
                                callback_group=group)
        self._action_server = ActionServer(
            self, MoveTo, 'gantry/move_to', execute_callback=self._execute_move,
            goal_callback=lambda goal: GoalResponse.ACCEPT,
            cancel_callback=self._cancel_move, callback_group=group)
        self._wakeup = self.create_guard_condition(self._drain_link_events, group)
        self._diagnostics_timer = self.create_timer(settings.diagnostics_period_s,
                                                    self._publish_diagnostics,
                                                    callback_group=group)
        self._link = GrblLink(link_config_from(settings), self._motion, self._on_link_event,
                              self._on_link_log)
        self._publish_state()
        self._link.start()
        self.get_logger().info(f'gantry_driver_node driving {settings.port} '
                               f'({settings.streaming_mode}, {settings.new_target_policy})')

    # -- parameters ---------------------------------------------------------------------------

    def _apply_settings(self, settings: GantryDriverSettings) -> None:
        self.settings = settings
        self._motion = settings.motion_config()
        self._link.reconfigure(link_config_from(settings), self._motion)
        self._diagnostics_timer.timer_period_ns = int(settings.diagnostics_period_s * 1e9)

    # -- link events (I/O thread -> executor) -------------------------------------------------

    def _on_link_event(self, event: LinkEvent) -> None:
        """Runs in the link's I/O thread: queue the event and wake the executor."""
        self._events.put(event)
        self._wakeup.trigger()

    def _on_link_log(self, level: str, message: str) -> None:
        # One call site per severity: rclpy refuses a severity change at one call site.
        logger = self.get_logger()
        if level == 'info':
            logger.info(message)
        elif level == 'warn':
            logger.warning(message)
        else:
            logger.error(message)

    def _drain_link_events(self) -> None:
        snapshot_changed = False
        while True:
            try:
                event = self._events.get_nowait()
            except queue.Empty:
                break
            if isinstance(event, GantrySnapshot):
                self._snapshot = event
                snapshot_changed = True
            elif isinstance(event, MoveFeedback):
                goal_handle = self._goal_handles.get(event.job_id)
                if goal_handle is not None and goal_handle.is_active:
                    goal_handle.publish_feedback(to_feedback(event))
            elif isinstance(event, MoveFinished):
                self._on_move_finished(event)
                snapshot_changed = True
            elif isinstance(event, RequestFinished):
                future = self._request_futures.pop(event.request_id, None)
                if future is not None:
                    future.set_result(event)
        if snapshot_changed:
            self._publish_state()

    def _on_move_finished(self, event: MoveFinished) -> None:
        if event.outcome.startswith('refused'):
            self._last_rejection = event.outcome
            self.get_logger().warning(f'move {event.job_id} {event.outcome}',
                                      throttle_duration_sec=1.0)
        elif not event.success:
            self.get_logger().warning(f'move {event.job_id} failed: {event.outcome}')
        else:
            self.get_logger().info(f'move {event.job_id} reached {event.world_position_m} m')
        future = self._move_futures.pop(event.job_id, None)
        if future is not None:
            future.set_result(event)

    def _publish_state(self) -> None:
        stamp = self.get_clock().now().to_msg()
        self._state_pub.publish(to_gantry_state(self._snapshot, self._last_rejection, stamp,
                                                self.settings.world.world_frame))
        joints = to_joint_state(self._snapshot, self.settings.joint_names, stamp)
        if joints is not None:
            self._joint_pub.publish(joints)

    def _publish_diagnostics(self) -> None:
        self._diagnostics_pub.publish(to_diagnostics(
            self._snapshot, self.get_name(), self.get_clock().now().to_msg()))

    # -- targets ------------------------------------------------------------------------------

    def _validate_target(self, msg: PointStamped, source: str) -> Vector3 | None:
        """Check a target; on refusal log it, publish it in gantry/state, return None."""
        point, frame_id, age_s = target_from_point_stamped(
            msg, self.get_clock().now().nanoseconds)
        try:
            target = check_target(point, frame_id, self.settings.world.world_frame, age_s,
                                  self.settings.max_target_age_s, self._motion.limits)
            plan_move(target, None, 0.0, self._motion)  # the approach offset must fit too
        except TargetRejectedError as error:
            self._reject(source, error.reason)
            return None
        return target

    def _reject(self, source: str, reason: str) -> None:
        """Log a refused request once per second at most and show it in gantry/state."""
        self._last_rejection = f'{source}: {reason}'
        self.get_logger().warning(f'rejected target from {source}: {reason}',
                                  throttle_duration_sec=1.0)
        self._publish_state()

    def _on_best_point(self, msg: PointStamped) -> None:
        target = self._validate_target(msg, 'best_point')
        if target is not None:
            self._link.submit_move(target)

    async def _execute_move(self, goal_handle: ServerGoalHandle) -> MoveTo.Result:
        request = goal_handle.request
        target = self._validate_target(request.target, 'gantry/move_to')
        if target is not None:
            try:
                check_feed(request.feed_rate_mm_min, self._motion)
            except TargetRejectedError as error:
                self._reject('gantry/move_to', error.reason)
                target = None
        if target is None:
            goal_handle.abort()
            return to_result(MoveFinished(0, False, f'refused: {self._last_rejection}',
                                          self._snapshot.world_position_m))
        future = Future()
        job_id = self._link.submit_move(target, request.feed_rate_mm_min)
        self._move_futures[job_id] = future
        self._goal_handles[job_id] = goal_handle
        try:
            finished: MoveFinished = await future
        finally:
            self._goal_handles.pop(job_id, None)
        if goal_handle.is_cancel_requested and not finished.success:
            goal_handle.canceled()
        elif finished.success:
            goal_handle.succeed()
        else:
            goal_handle.abort()
        return to_result(finished)

    def _cancel_move(self, goal_handle: ServerGoalHandle) -> CancelResponse:
        for job_id, handle in self._goal_handles.items():
            if handle is goal_handle:
                self._link.cancel_move(job_id)
        return CancelResponse.ACCEPT

    # -- services -----------------------------------------------------------------------------

    def _make_request_callback(self, kind: str) -> Any:
        async def callback(request: Trigger.Request,
                           response: Trigger.Response) -> Trigger.Response:
            future = Future()
            self._request_futures[self._link.request(kind)] = future
            finished: RequestFinished = await future
            response.success, response.message = finished.success, finished.message
            self.get_logger().info(f'gantry/{kind}: {finished.message}')
            return response
        return callback

    def destroy_node(self) -> None:
        """Close the serial link (its thread first), then the node."""
        self._link.close()
        self._action_server.destroy()
        super().destroy_node()


def main(args: list[str] | None = None) -> None:
    """Run the node until shutdown; a bad parameter ends it with one FATAL line, exit code 1."""
    run_node(GantryDriverNode, args)


if __name__ == '__main__':
    main()
