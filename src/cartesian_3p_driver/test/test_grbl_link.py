"""The serial runner's own rules (no port, no thread): back-off and reminders; `$$` parsing."""

from cartesian_3p_driver.grbl_link import ReconnectSchedule
from cartesian_3p_driver.grbl_settings_check import MachineSettings, parse_setting


def test_reconnect_delays_double_up_to_the_maximum_and_reset_on_success():
    schedule = ReconnectSchedule(0.5, 5.0, reminder_period_s=30.0)
    delays = []
    for _ in range(6):
        schedule.failed(100.0)
        delays.append(schedule.next_attempt - 100.0)
    assert delays == [0.5, 1.0, 2.0, 4.0, 5.0, 5.0]
    schedule.succeeded()
    schedule.failed(200.0)
    assert schedule.next_attempt == 200.5


def test_a_lasting_failure_is_logged_at_once_then_as_a_periodic_reminder():
    schedule = ReconnectSchedule(0.5, 5.0, reminder_period_s=30.0)
    logged = [now for now in range(0, 100, 5) if schedule.failed(float(now))]
    assert logged == [0, 30, 60, 90]
    schedule.succeeded()
    assert schedule.failed(101.0)                        # a new outage is logged at once


def test_dollar_dollar_lines_parse_and_others_do_not():
    assert parse_setting('$130=400.000') == (130, 400.0)
    assert parse_setting('$20=1') == (20, 1.0)
    for line in ('ok', '[MSG:x]', '$N0=', '$130=abc', '<Idle|MPos:0,0,0>'):
        assert parse_setting(line) is None
    values = {20: 1.0, 110: 6000.0, 111: 6000.0, 112: 3000.0, 130: 400.0, 131: 300.0,
              132: 200.0}
    settings = MachineSettings.from_values(values)
    assert settings.max_travel_mm == (400.0, 300.0, 200.0) and settings.soft_limits
