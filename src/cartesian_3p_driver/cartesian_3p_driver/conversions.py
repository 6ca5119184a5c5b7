"""The one module that converts between messages and the driver's domain types."""

from __future__ import annotations

from collections.abc import Sequence

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, PointStamped
from sensor_msgs.msg import JointState
from std_msgs.msg import Header

from stereo_fuzzy_msgs.action import MoveTo
from stereo_fuzzy_msgs.msg import GantryState

from .gcode import Vector3
from .link_events import GantrySnapshot, MoveFeedback, MoveFinished


def target_from_point_stamped(msg: PointStamped, now_ns: int) -> tuple[Vector3, str, float | None]:
    """Return (point [m], frame_id, age [s] or None when unstamped) of a target message."""
    stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
    age_s = None if stamp_ns == 0 else (now_ns - stamp_ns) / 1e9
    return (msg.point.x, msg.point.y, msg.point.z), msg.header.frame_id, age_s


def to_point(vector: Vector3 | None) -> Point:
    """Return a Point [m] (the origin when unknown)."""
    if vector is None:
        return Point()
    return Point(x=float(vector[0]), y=float(vector[1]), z=float(vector[2]))


def to_gantry_state(snapshot: GantrySnapshot, last_rejection: str, stamp: Time,
                    frame_id: str) -> GantryState:
    """Return the GantryState message for a link snapshot (machine position in metres)."""
    machine = snapshot.machine_position_mm
    return GantryState(
        header=Header(stamp=stamp, frame_id=frame_id),
        state=snapshot.state,
        sub_state=snapshot.sub_state,
        connected=snapshot.connected,
        homing_required=snapshot.homing_required,
        machine_position=to_point(None if machine is None else
                                  (machine[0] / 1000.0, machine[1] / 1000.0,
                                   machine[2] / 1000.0)),
        world_position=to_point(snapshot.world_position_m),
        feed_rate_mm_min=float(snapshot.feed_mm_min),
        pins=snapshot.pins,
        last_error_code=snapshot.last_error_code,
        # A settings mismatch has no Grbl code: it shows as a text with code 0.
        last_error_text=snapshot.last_error_text or (
            f'controller settings refuse motion: {snapshot.settings_problem}'
            if snapshot.settings_problem else ''),
        last_alarm_code=snapshot.last_alarm_code,
        last_alarm_text=snapshot.last_alarm_text,
        last_rejection=last_rejection,
        lines_queued=snapshot.lines_queued,
        lines_sent=snapshot.lines_sent,
        lines_acknowledged=snapshot.lines_acknowledged,
    )


def to_joint_state(snapshot: GantrySnapshot, joint_names: Sequence[str],
                   stamp: Time) -> JointState | None:
    """Return the three prismatic joints at the tool's world position [m], if known."""
    if snapshot.world_position_m is None:
        return None
    return JointState(header=Header(stamp=stamp), name=list(joint_names),
                      position=[float(value) for value in snapshot.world_position_m])


def to_diagnostics(snapshot: GantrySnapshot, name: str, stamp: Time) -> DiagnosticArray:
    """Return /diagnostics for the serial link: connection, line counts, last error."""
    if snapshot.fault or snapshot.state in ('Alarm', 'Disconnected'):
        level = DiagnosticStatus.ERROR
        message = snapshot.fault or snapshot.link_state
        if snapshot.link_error and snapshot.link_error not in message:
            message = f'{message} ({snapshot.link_error})'
    elif snapshot.homing_required or not snapshot.connected:
        level, message = DiagnosticStatus.WARN, snapshot.link_state
    else:
        level, message = DiagnosticStatus.OK, f'{snapshot.state}, {snapshot.link_state}'
    last_error = (f'error:{snapshot.last_error_code} {snapshot.last_error_text}'
                  if snapshot.last_error_code else snapshot.link_error)
    last_alarm = (f'ALARM:{snapshot.last_alarm_code} {snapshot.last_alarm_text}'
                  if snapshot.last_alarm_code else '')
    values = {
        'port': snapshot.port,
        'connection': snapshot.link_state,
        'state': snapshot.state,
        'homing_required': str(snapshot.homing_required),
        'lines_sent': str(snapshot.lines_sent),
        'lines_acknowledged': str(snapshot.lines_acknowledged),
        'lines_sent_total': str(snapshot.total_lines_sent),
        'lines_queued': str(snapshot.lines_queued),
        'reconnections': str(snapshot.reconnections),
        'last_error': last_error,
        'last_alarm': last_alarm,
        'fault': snapshot.fault,
        'controller_settings': snapshot.settings_problem or (
            'fit the driver parameters' if snapshot.connected else 'not checked yet'),
    }
    status = DiagnosticStatus(level=level, name=f'{name}: serial link', message=message,
                              hardware_id=snapshot.port,
                              values=[KeyValue(key=k, value=v) for k, v in values.items()])
    return DiagnosticArray(header=Header(stamp=stamp), status=[status])


def to_feedback(event: MoveFeedback) -> MoveTo.Feedback:
    """Return action feedback for a move's progress."""
    return MoveTo.Feedback(current_position=to_point(event.world_position_m),
                           state=event.state, distance_remaining=event.distance_remaining_m)


def to_result(event: MoveFinished) -> MoveTo.Result:
    """Return the action result of a finished (or refused) move."""
    return MoveTo.Result(success=event.success, outcome=event.outcome,
                         final_position=to_point(event.world_position_m))
