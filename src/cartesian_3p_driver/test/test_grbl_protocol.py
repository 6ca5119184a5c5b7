"""Grbl 1.1 reply classification and status-report parsing on real-format lines (no ROS)."""

import pytest
from cartesian_3p_driver.grbl_protocol import (
    ProtocolError,
    ReplyKind,
    alarm_text,
    classify,
    error_text,
    parse_status_report,
)


@pytest.mark.parametrize(('line', 'kind', 'code'), [
    ('ok', ReplyKind.OK, 0),
    ('error:9', ReplyKind.ERROR, 9),
    ('ALARM:2', ReplyKind.ALARM, 2),
    ("Grbl 1.1h ['$' for help]", ReplyKind.BANNER, 0),
    ("GrblHAL 1.1f ['$' or '$HELP' for help]", ReplyKind.BANNER, 0),
    ("[MSG:'$H'|'$X' to unlock]", ReplyKind.MESSAGE, 0),
    ('$130=400.000', ReplyKind.SETTING, 0),
    ('<Idle|MPos:0.000,0.000,0.000|FS:0,0>', ReplyKind.STATUS, 0),
    ('>G20:ok', ReplyKind.ECHO, 0),
    ('o#k', ReplyKind.UNKNOWN, 0),
])
def test_classify(line, kind, code):
    reply = classify(line + '\r\n')
    assert (reply.kind, reply.code) == (kind, code)


def test_codes_have_meanings():
    assert 'alarm or jog' in error_text(9)
    assert 'Soft limit' in alarm_text(2)
    assert 'unknown' in error_text(999)


def test_hold_substate_with_mpos_and_fs():
    report = parse_status_report('<Hold:0|MPos:10.000,-2.500,3.125|FS:0,0>')
    assert (report.state, report.sub_state) == ('Hold', 0)
    assert report.machine_position_mm == (10.0, -2.5, 3.125)
    assert (report.feed_mm_min, report.spindle_rpm) == (0.0, 0.0)
    assert report.pins == ''


def test_run_with_pins_buffer_and_line_number():
    report = parse_status_report(
        '<Run|MPos:-1.000,0.000,5.000|Bf:15,128|Ln:99|FS:500,0|Pn:XZ|Ov:100,100,100>')
    assert report.state == 'Run' and report.sub_state == -1
    assert report.buffer == (15, 128)
    assert report.line_number == 99
    assert report.feed_mm_min == 500.0
    assert report.pins == 'XZ'
    assert report.fields['Ov'] == '100,100,100'


def test_wpos_with_wco_resolves_machine_position_now_and_later():
    first = parse_status_report('<Idle|WPos:1.000,2.000,3.000|FS:0,0|WCO:10.000,20.000,30.000>')
    assert first.machine_position_mm is None
    assert first.resolve_machine_position(None) == (11.0, 22.0, 33.0)
    later = parse_status_report('<Door:2|WPos:0.000,0.000,0.000|F:100>')
    assert (later.state, later.sub_state, later.feed_mm_min) == ('Door', 2, 100.0)
    assert later.resolve_machine_position(None) is None
    assert later.resolve_machine_position(first.work_offset_mm) == (10.0, 20.0, 30.0)


@pytest.mark.parametrize('line', [
    'Idle|MPos:0,0,0',                   # no brackets
    '<Bogus|MPos:0,0,0>',                # unknown state
    '<Idle|FS:0,0>',                     # no position
    '<Idle|MPos:0,x,0>',                 # bad number
    '<Idle|MPos:0,0>',                   # two axes
    '<Hold:a|MPos:0,0,0>',               # bad sub-state
    '<Idle|MPos>',                       # field without value
])
def test_malformed_reports_raise(line):
    with pytest.raises(ProtocolError):
        parse_status_report(line)
