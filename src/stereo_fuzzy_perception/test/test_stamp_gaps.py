"""StampGaps estimates the frames a stream lost from gaps in its own header stamps."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st
from stereo_fuzzy_perception.core.stamp_gaps import StampGaps

PERIOD_NS = 33_333_333  # a 30 Hz camera
START_NS = 1_700_000_000 * 10**9


def observe_frames(gaps: StampGaps, frames: list[int], jitter_ns: list[int] | None = None,
                   ) -> None:
    """Observe frames numbered `frames` of a stream at PERIOD_NS, each shifted by its jitter."""
    for index, frame in enumerate(frames):
        shift = jitter_ns[index] if jitter_ns else 0
        gaps.observe(START_NS + frame * PERIOD_NS + shift)


def test_a_steady_stream_loses_nothing_and_its_period_is_measured():
    gaps = StampGaps()
    observe_frames(gaps, list(range(100)))
    assert gaps.estimated_lost == 0
    assert gaps.period_ns == pytest.approx(PERIOD_NS)
    assert gaps.report('left/image_raw')['left/image_raw stamp period [s]'] == '0.033333'


def test_gaps_count_the_frames_between_and_held_intervals_count_once_learned():
    gaps = StampGaps(learn_intervals=8)
    # Frames 3-4 and 10-19 are missing; the first gap arrives while the period is learned.
    frames = [0, 1, 2, 5, 6, 7, 8, 9, 20, 21, 22]
    observe_frames(gaps, frames)
    assert gaps.estimated_lost == 2 + 10
    assert gaps.received + gaps.estimated_lost == frames[-1] + 1


def test_nothing_is_estimated_before_the_period_is_learned():
    gaps = StampGaps(learn_intervals=8)
    observe_frames(gaps, [0, 1, 5])
    assert (gaps.period_ns, gaps.estimated_lost) == (0.0, 0)
    assert gaps.report('x')['x stamp period [s]'] == 'not yet measured'


def test_restarts_and_unstamped_messages_are_counted_not_estimated():
    gaps = StampGaps(learn_intervals=2)
    observe_frames(gaps, [0, 1, 2, 3, 0, 1, 2])  # a looped bag starts its stamps again
    gaps.observe(0)
    assert (gaps.received, gaps.estimated_lost, gaps.restarts, gaps.unstamped) == (8, 0, 1, 1)


def test_a_period_learned_inside_a_loss_is_corrected_by_later_single_frames():
    gaps = StampGaps(learn_intervals=4, period_window=8)
    observe_frames(gaps, [0, 10, 20, 30, 40])  # learned: 10 periods
    assert gaps.period_ns == pytest.approx(10 * PERIOD_NS)
    observe_frames(gaps, list(range(41, 60)))
    assert gaps.period_ns == pytest.approx(PERIOD_NS)
    before = gaps.estimated_lost
    observe_frames(gaps, [63])
    assert gaps.estimated_lost - before == 3


def test_bad_settings_are_refused_with_their_values():
    with pytest.raises(ValueError, match='learn_intervals \\(0\\)'):
        StampGaps(learn_intervals=0)


@given(st.lists(st.booleans(), min_size=1, max_size=400),
       st.lists(st.integers(-PERIOD_NS // 10, PERIOD_NS // 10), min_size=420, max_size=420))
def test_received_plus_estimated_is_what_was_sent_between_the_first_and_last(kept, jitter):
    """With the period learned from 9 leading frames, jitter of +-10 % does not bias it."""
    gaps = StampGaps()
    frames = list(range(9)) + [9 + index for index, keep in enumerate(kept) if keep]
    observe_frames(gaps, frames, jitter[:len(frames)])
    assert gaps.received + gaps.estimated_lost == frames[-1] + 1
    assert gaps.restarts == 0 and gaps.unstamped == 0
