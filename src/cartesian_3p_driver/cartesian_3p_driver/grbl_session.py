"""The driver's side of a Grbl 1.1 conversation: protocol and safety rules, without I/O.

ROS-free and I/O-free, like the simulator's controller model (grbl_controller.py) it talks
to in the unit tests. Bytes and time go in (`connection_opened`, `receive`, `tick`,
`connection_lost`) along with the caller's commands (`submit_move`, `cancel_move`,
`request`); bytes to write come out of `data_to_send` and events out of `events`. The serial
runner (grbl_link.py) owns the port, the thread and the reconnection back-off.

Where the conversation stands is one Stage, changed only by `_enter`. Two latches sit beside
it, because they outlive connections and resets: the lock-out after a fault, and the homing
required after a reconnection.

Safety rules enforced here:
- Nothing moves before the banner was seen and the preamble acknowledged.
- Each line is written exactly once; nothing is ever replayed after a fault or a reconnect.
- error:N, ALARM:N, a garbled or missing reply stop streaming, drop the host queue and latch
  a fault that only gantry/unlock or gantry/home clears.
- After a reconnection, motion is refused until the controller was homed again.
- A move is finished only when the controller reports Idle at the goal.
"""

from __future__ import annotations

from dataclasses import replace

from .gcode import PREAMBLE
from .grbl_protocol import (
    CRITICAL_ALARMS,
    SOFT_RESET,
    ProtocolError,
    ReplyKind,
    StatusReport,
    alarm_text,
    classify,
    error_text,
    parse_status_report,
)
from .grbl_settings_check import MachineSettings, parse_setting, settings_problem
from .line_streamer import StreamingError
from .link_events import DISCONNECTED, CloseLink, RequestFinished
from .session_core import FAST_POLL_PERIOD_S, SETTLED_STAGES, Lockout, Stage
from .session_requests import SessionRequests

#: The one line the driver writes to read the controller's settings.
READ_SETTINGS = '$$'


class GrblSession(SessionRequests):
    """The driver's Grbl protocol and safety state machine: no I/O, time passed in.

    Args:
        config: Protocol settings (timeouts, streaming mode, policies).
        motion: Motion planning settings (transform, limits, approach, feeds).
        port_name: The port, as shown in snapshots and diagnostics.
    """

    # -- connection ---------------------------------------------------------------------------

    def connection_opened(self, now: float) -> None:
        """A port to the controller was opened at `now` [s]: wait for its banner."""
        self._streamer = self._new_streamer()
        self._rx.clear()
        self._out.data.clear()
        self._opened_at = self._last_rx_at = self._last_poll_at = now
        self._waiting_since = None
        self._closed_reason = ''
        self.machine_settings, self.settings_problem = None, ''
        self._enter(Stage.AWAITING_BANNER)
        self._emit_snapshot(link_error='')

    def connection_failed(self, reason: str) -> None:
        """Opening the port failed (no session yet): show why in snapshots."""
        self._closed_reason = reason
        self._emit_snapshot(link_error=reason)

    def connection_lost(self, reason: str, now: float) -> None:
        """The port failed or was closed: fail everything; homing is required afterwards."""
        if self.stage is Stage.CLOSED:
            return
        had_controller = self.controller_seen
        self._log('error', f'gantry link: {reason}; controller disconnected, retrying with '
                           'back-off; homing will be required')
        self._enter(Stage.CLOSED)
        self._closed_reason = f'disconnected: {reason}'
        self._out.data.clear()
        self._report = None
        outcome = f'serial link lost ({reason})'
        self._fail_all_moves(outcome)
        self._finish_system(False, outcome)
        if self._stop is not None:
            if self._stop.request_id is not None:
                self._finished(RequestFinished(self._stop.request_id, False, outcome))
            self._stop = None
        if had_controller:
            self.homing_required = True
            self._snapshot = replace(self._snapshot,
                                     reconnections=self._snapshot.reconnections + 1)
        self._emit_snapshot(state=DISCONNECTED, sub_state=-1, feed_mm_min=0.0, link_error=reason)

    def _give_up(self, reason: str, now: float) -> None:
        self.connection_lost(reason, now)
        self._events.append(CloseLink(reason))

    # -- bytes in -----------------------------------------------------------------------------

    def receive(self, data: bytes, now: float) -> None:
        """Take bytes read from the controller at `now` [s]."""
        if not self.is_open or not data:
            return
        self._last_rx_at = now
        self._rx.extend(data)
        while self.is_open:
            cut = [i for i in (self._rx.find(b'\n'), self._rx.find(b'\r')) if i >= 0]
            if not cut:
                break
            index = min(cut)
            text = bytes(self._rx[:index]).decode('ascii', errors='replace').strip()
            del self._rx[:index + 1]
            if text:
                self._handle_line(text, now)
        self._progress(now)

    def _handle_line(self, text: str, now: float) -> None:
        reply = classify(text)
        if reply.kind is ReplyKind.BANNER:
            self._on_banner(text, now)
        elif not self.controller_seen:
            return  # noise before the banner (boot loader, a half line)
        elif reply.kind is ReplyKind.STATUS:
            try:
                report = parse_status_report(text)
            except ProtocolError as error:
                self._log('warn', f'gantry link: ignoring malformed status report: {error}')
                return
            self._on_status(report, now)
        elif reply.kind in (ReplyKind.OK, ReplyKind.ERROR):
            self._on_reply(reply.kind is ReplyKind.OK, reply.code, now)
        elif reply.kind is ReplyKind.ALARM:
            self._on_alarm(reply.code, now)
        elif reply.kind is ReplyKind.SETTING:
            setting = parse_setting(text)
            if setting is not None and self.stage is Stage.READING_SETTINGS:
                self._setting_values[setting[0]] = setting[1]
        elif reply.kind is ReplyKind.MESSAGE:
            if 'Reset to continue' in text and self.lockout is Lockout.FAULT:
                self.lockout = Lockout.FAULT_RESET_FIRST
            self._log('info', f'gantry controller: {text}')
        elif reply.kind is ReplyKind.UNKNOWN:
            line = self._streamer.oldest_in_flight()
            if line is None:
                self._log('warn', f'gantry link: ignoring unrecognised line {text!r}')
                return
            self._streamer.forget_in_flight()
            self._set_fault(f'unrecognised reply {text!r} while waiting for the reply to '
                            f'{line!r}; streaming stopped', now)

    def _on_banner(self, text: str, now: float) -> None:
        first = not self.controller_seen
        expected = self.stage is Stage.RESETTING
        lost = self._streamer.forget_in_flight() + self._streamer.drop_queue()
        self._waiting_since = None
        if self.lockout is Lockout.FAULT_RESET_FIRST:
            self.lockout = Lockout.FAULT
        self._enter(Stage.QUERYING_STATE)
        if first:
            self._log('info', f'gantry link: controller says {text!r}')
        elif expected:
            self._log('info', 'gantry link: controller reset as requested')
        else:
            self._log('warn', f'gantry link: unexpected controller reset ({text!r}); '
                              f'{len(lost)} unanswered line(s) discarded, none re-sent')
            self._fail_all_moves('controller reset unexpectedly')
            self._finish_system(False, 'controller reset unexpectedly')
        if expected and self._stop is not None and self._stop.done_at_banner:
            self._end_stop(True, self._stop.done_at_banner)
        self._query_status(now)
        self._emit_snapshot(link_error='')

    def _on_status(self, report: StatusReport, now: float) -> None:
        if report.work_offset_mm is not None:
            self._wco = report.work_offset_mm
        self._report = report
        if self.stage is Stage.QUERYING_STATE:
            if self.machine_settings is None and not self.settings_problem:
                # Once per connection, before anything else is sent: $$ (Idle or Alarm).
                self._enter(Stage.READING_SETTINGS)
                self._setting_values = {}
                self._streamer.enqueue([READ_SETTINGS])
            else:
                self._enter(Stage.STATE_KNOWN)
        machine = report.resolve_machine_position(self._wco)
        world = self.motion.transform.to_world(machine) if machine is not None else None
        self._snapshot = replace(
            self._snapshot, state=report.state, sub_state=report.sub_state,
            machine_position_mm=machine, world_position_m=world,
            feed_mm_min=report.feed_mm_min or 0.0, pins=report.pins)
        if self.stage is Stage.FEED_HOLD:
            assert self._stop is not None
            if report.state == 'Alarm':
                self._end_stop(False, 'controller raised an alarm during the stop')
            elif report.state == 'Hold' and report.sub_state == 0:
                # Only Hold:0 (a feed hold in Idle gives Hold:0 too): a stale Idle report
                # from before the `!` must not trigger a reset while a block starts.
                self._enter(Stage.RESETTING)
                self._stop.deadline = now + self.config.stop_timeout_s
                self._out.write(SOFT_RESET)
        if machine is not None and world is not None:
            self._moves.on_status(report, machine, world, self.config.position_tolerance_mm)
        self._emit_snapshot()

    # -- time ---------------------------------------------------------------------------------

    def tick(self, now: float) -> None:
        """Run the timers up to `now` [s]: banner wait, timeouts, status polling."""
        if self.stage is Stage.CLOSED:
            return
        config = self.config
        if not self.controller_seen:
            if now - self._opened_at <= config.banner_timeout_s:
                return
            if self.stage is Stage.AWAITING_BANNER:
                self._enter(Stage.AWAITING_BANNER_AFTER_RESET)
                self._opened_at = now
                self._log('info', 'gantry link: no banner yet, sending a soft reset')
                self._out.write(SOFT_RESET)
            else:
                self._give_up(f'no Grbl banner within {2 * config.banner_timeout_s:.1f} s', now)
            return
        homing = self._homing()
        if not homing and now - self._last_rx_at > config.link_timeout_s:
            self._give_up(f'no data from the controller for {config.link_timeout_s:.1f} s', now)
            return
        self._check_reply_timeout(now, homing)
        stop = self._stop
        if stop is not None and now > stop.deadline:
            self._end_stop(False, 'controller did not reach Hold:0 and reset within '
                                  f'{config.stop_timeout_s:.1f} s')
        period = FAST_POLL_PERIOD_S if self._stop is not None else config.poll_period_s
        if now - self._last_poll_at >= (max(period, 1.0) if homing else period):
            self._query_status(now)  # Grbl may not answer while homing; harmless
        self._progress(now)

    def _check_reply_timeout(self, now: float, homing: bool) -> None:
        if self._waiting_since is None or not self._streamer.in_flight:
            return
        limit = self.config.homing_timeout_s if homing else self.config.reply_timeout_s
        if now - self._waiting_since <= limit:
            return
        line = self._streamer.oldest_in_flight()
        self._streamer.forget_in_flight()
        self._waiting_since = None
        reason = f'no reply to {line!r} within {limit:.1f} s'
        if self.stage is Stage.READING_SETTINGS:
            self._settings_read(f'no reply to $$ within {limit:.1f} s')
        if self.stage is Stage.SYSTEM_COMMAND:
            self._end_system(False, reason)
        self._set_fault(f'{reason} (lost reply?); streaming stopped, nothing re-sent', now)

    # -- outgoing -----------------------------------------------------------------------------

    def _progress(self, now: float) -> None:
        """Send what may be sent now: preamble, home/unlock, the next move's lines."""
        if self.stage is Stage.CLOSED:
            return
        streamer = self._streamer
        report = self._report
        if self.stage is Stage.STATE_KNOWN and self._system is None and report is not None \
                and report.state != 'Alarm' and not streamer.in_flight:
            self._enter(Stage.SENDING_PREAMBLE)
            streamer.enqueue(PREAMBLE)
        system = self._system
        if system is not None and self.stage in SETTLED_STAGES and not streamer.in_flight \
                and self._stop is None:
            if self.lockout is Lockout.FAULT_RESET_FIRST:
                # After a hard/soft-limit alarm Grbl accepts $X/$H only after a reset.
                self._enter(Stage.RESETTING)
                self._out.write(SOFT_RESET)
            else:
                system.resume_stage = self.stage
                self._enter(Stage.SYSTEM_COMMAND)
                streamer.enqueue([system.line])
        if self._may_move() is None:
            started = self._moves.start_next(self.motion, self._snapshot.world_position_m)
            if started is not None:
                self._stream_move(*started)
        if streamer.pump() and self._waiting_since is None:
            self._waiting_since = now

    def _stream_move(self, job_id: int, lines: tuple[str, ...]) -> None:
        try:
            self._streamer.enqueue(lines)
        except StreamingError as error:
            self._fail_all_moves(f'refused: {error}')
            return
        self._log('info', f'gantry link: move {job_id}: {len(lines)} line(s)')

    # -- replies ------------------------------------------------------------------------------

    def _on_reply(self, ok: bool, code: int, now: float) -> None:
        try:
            line = self._streamer.acknowledge()
        except StreamingError:
            if self.lockout is not Lockout.NONE:
                self._log('warn', 'gantry link: ignoring a reply after the fault')
                return
            self._set_fault(f"{'ok' if ok else f'error:{code}'} arrived with no line in "
                            'flight (replies out of step); streaming stopped', now)
            return
        self._waiting_since = now if self._streamer.in_flight else None
        if self.stage is Stage.READING_SETTINGS and line == READ_SETTINGS:
            self._settings_read(f'the controller refused $$ (error:{code})' if not ok else '')
            return
        system = self._system
        if self.stage is Stage.SYSTEM_COMMAND and system is not None and line == system.line:
            if ok:
                self._on_system_ok(system, now)
            else:
                self._end_system(False, f'{line} refused: error:{code} ({error_text(code)})')
                self._emit_snapshot(last_error_code=code, last_error_text=error_text(code))
            return
        if not ok:
            meaning = error_text(code)
            self._emit_snapshot(last_error_code=code, last_error_text=meaning)
            self._set_fault(f'error:{code} ({meaning}) for line {line!r}; streaming stopped', now)
            return
        if self.stage is Stage.SENDING_PREAMBLE and line in PREAMBLE \
                and self._streamer.idle:
            self._enter(Stage.READY)
            self._log('info', 'gantry link: controller ready (preamble acknowledged)')
            self._on_ready()
        else:
            self._moves.line_acknowledged(now)
        self._emit_snapshot()

    def _settings_read(self, failure: str) -> None:
        """Check the $$ settings (or record why they could not be read); logged once."""
        problem = failure
        if not problem:
            try:
                self.machine_settings = MachineSettings.from_values(self._setting_values)
            except ValueError as error:
                problem = str(error)
        if self.machine_settings is not None:
            self._log('info', f'gantry link: controller settings: '
                              f'{self.machine_settings.describe()}')
            problem = settings_problem(self.machine_settings, self.motion)
            if not self.machine_settings.soft_limits:
                self._log('warn', "gantry link: the controller's soft limits ($20) are off: "
                                  "the driver's workspace check is the only travel limit")
        if problem:
            self.settings_problem = problem
            self._log('error', f'gantry link: motion refused, controller settings do not fit '
                               f'the driver parameters: {problem}')
        self._enter(Stage.STATE_KNOWN)
        self._emit_snapshot()

    def _on_ready(self) -> None:
        if self._done_when_ready is not None:
            done, self._done_when_ready = self._done_when_ready, None
            self._finished(done)
        if self._stop is not None:
            # READY is reached during a stop only through its reset: the stop is complete.
            self._end_stop(True, 'stopped')

    def _on_alarm(self, code: int, now: float) -> None:
        meaning = alarm_text(code)
        forgotten = self._streamer.forget_in_flight()
        self._waiting_since = None
        self._emit_snapshot(last_alarm_code=code, last_alarm_text=meaning)
        if self.stage is Stage.SYSTEM_COMMAND and self._system is not None:
            self._end_system(False, f'{self._system.line} ended in ALARM:{code} ({meaning})')
        self._set_fault(f'ALARM:{code} ({meaning}); {len(forgotten)} unanswered line(s) '
                        'discarded', now, stop_motion=False,
                        reset_first=code in CRITICAL_ALARMS)
