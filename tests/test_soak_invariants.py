"""The soak benchmark's invariant checks, on synthetic line logs and counters (no ROS)."""

from __future__ import annotations

import os

from benchmarks.soak_benchmark import (
    CORRELATION_STATUS,
    FUZZY_STATUS,
    SYNC_STATUS,
    MemorySample,
    accounting_from,
    line_log_problems,
    memory_problems,
    pair_problems,
    read_rss_kib,
)

MOVE_A = ['G53 G1 Z150.000 F1000.0', 'G53 G1 X100.000 Y200.000 F1500.0',
          'G53 G1 Z50.000 F1000.0']
MOVE_B = ['G53 G1 Z150.000 F1000.0', 'G53 G1 X120.000 Y180.000 F1500.0',
          'G53 G1 Z40.000 F1000.0']
# Connect, home, move A; its XY reply dropped -> fault; home; move B.
SENT = ['$$', '$H', 'G21 G90 G94', *MOVE_A[:2], '$H', 'G21 G90 G94', *MOVE_B]


def test_logs_that_agree_pass():
    assert line_log_problems(SENT, list(SENT), best_points=2) == []


def test_a_line_lost_on_the_way_is_found():
    received = SENT[:4] + SENT[5:]
    problems = line_log_problems(SENT, received, best_points=2)
    assert any('line 5' in problem for problem in problems), problems
    assert any('10 lines sent but 9 received' in problem for problem in problems), problems


def test_lines_out_of_order_are_found():
    received = list(SENT)
    received[8], received[9] = received[9], received[8]
    assert any('line 9' in problem for problem in line_log_problems(SENT, received, 2))


def test_a_re_sent_motion_line_is_found_even_when_both_sides_saw_it():
    sent = SENT[:5] + [SENT[4]] + SENT[5:]
    problems = line_log_problems(sent, list(sent), best_points=2)
    assert any('re-sent' in problem for problem in problems), problems


def test_a_repeated_system_line_is_no_resend():
    sent = ['$$', '$H', '$H', 'G21 G90 G94', *MOVE_A]
    assert line_log_problems(sent, list(sent), best_points=1) == []


def test_more_motion_lines_than_three_per_best_point_are_found():
    sent = ['$$', 'G21 G90 G94', *MOVE_A, '$H', *MOVE_A]
    assert any('more than 3 per target' in problem
               for problem in line_log_problems(sent, list(sent), best_points=1))


def diagnostics(sync_out: int, sync_dropped: int, correlation_processed: int,
                superseded: int, decided: int, received: int = 0) -> dict[str, dict[str, str]]:
    sync_received = sync_out + sync_dropped
    return {
        SYNC_STATUS: {'pairs out': str(sync_out), 'pairs dropped': str(sync_dropped),
                      **{f'received {topic}': str(sync_received)
                         for topic in ('left/image_raw', 'left/camera_info', 'right/image_raw',
                                       'right/camera_info')}},
        CORRELATION_STATUS: {'pairs received': str(received or sync_out),
                             'pairs processed': str(correlation_processed),
                             'dropped superseded': str(superseded), 'dropped encoding': '0'},
        FUZZY_STATUS: {'decisions made': str(decided - 1), 'decisions refused': '1'},
    }


def test_every_pair_decided_or_counted_as_dropped_passes():
    accounting = accounting_from(100, 95, diagnostics(99, 1, 95, 4, 95))
    assert accounting.counted_drops == 5
    assert pair_problems(accounting) == []


def test_a_pair_lost_without_a_count_is_found():
    # The correlation node received 98 of the 99 pairs the sync node published.
    accounting = accounting_from(100, 94, diagnostics(99, 1, 94, 4, 94, received=98))
    problems = pair_problems(accounting)
    assert any('94 decisions received' in problem and '= 95' in problem
               for problem in problems), problems
    assert any('correlation node received pairs 98, its input gave 99' in problem
               for problem in problems), problems


def test_camera_inputs_the_sync_node_missed_are_named_but_not_counted_as_drops():
    stats = diagnostics(97, 1, 94, 4, 94)
    stats[SYNC_STATUS].update({'left/image_raw estimated lost (stamp gaps)': '2',
                               'lost before delivery left/image_raw': '1'})
    accounting = accounting_from(100, 94, stats)
    assert accounting.counted_drops == 5  # the estimate does not balance the identity
    problems = pair_problems(accounting)
    assert any('sync node received complete scenes 98, its input gave 100' in problem
               for problem in problems), problems
    assert any('2 estimated from stamp gaps, 1 reported lost by DDS' in problem
               for problem in problems), problems


def test_memory_growth_above_the_limit_is_found():
    warm = MemorySample(120.0, 'warm-up', {'correlation_node': 200_000, 'fake_gantry': 50_000})
    end = MemorySample(600.0, 'end', {'correlation_node': 230_000, 'fake_gantry': 50_500})
    problems = memory_problems(warm, end, max_growth_pct=10.0)
    assert len(problems) == 1 and 'correlation_node' in problems[0], problems
    gone = memory_problems(warm, MemorySample(600.0, 'end', {'fake_gantry': 50_000}), 10.0)
    assert gone == ['correlation_node: no memory sample at the end (process gone)']


def test_resident_memory_is_read_from_proc():
    rss = read_rss_kib(os.getpid())
    assert rss is not None and rss > 1000
    assert read_rss_kib(2 ** 22 + 7) is None  # above the kernel's largest pid
