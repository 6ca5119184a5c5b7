"""SequenceGaps counts every message a subscriber never received, from sequence numbers."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st
from stereo_fuzzy_perception.core.sequence_gaps import SequenceGaps


def test_gaps_restarts_and_unnumbered_messages_are_counted():
    gaps = SequenceGaps()
    for number in (5, 6, 9, 10, 0, 2, 3):
        gaps.observe(number)
    assert (gaps.received, gaps.lost, gaps.restarts, gaps.unnumbered) == (7, 2, 1, 1)
    assert gaps.before_first == 4 + 1  # 1-4 before the first 5, 1 before the restart at 2
    assert gaps.report('stereo/pair')['stereo/pair lost (sequence gaps)'] == 2


@given(st.integers(1, 10**6), st.lists(st.booleans(), max_size=300))
def test_received_plus_lost_plus_before_first_is_what_was_sent(start, delivered):
    gaps = SequenceGaps()
    gaps.observe(start)
    numbers = [start + 1 + index for index, kept in enumerate(delivered) if kept]
    for number in numbers:
        gaps.observe(number)
    last = numbers[-1] if numbers else start
    assert gaps.received + gaps.lost + gaps.before_first == last
    assert gaps.restarts == 0 and gaps.unnumbered == 0
