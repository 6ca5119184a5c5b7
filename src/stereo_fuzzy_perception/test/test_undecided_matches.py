"""UndecidedMatches: the matches in flight between correlation_node and the fuzzy stage."""

from __future__ import annotations

import pytest
from stereo_fuzzy_perception.core.matching.undecided_matches import UndecidedMatches


def test_a_new_match_waits_only_while_the_limit_is_undecided():
    undecided = UndecidedMatches()
    assert undecided.wait_s(0.0, 2, 0.5) == 0.0
    undecided.published(1, 0.0)
    assert undecided.wait_s(0.01, 2, 0.5) == 0.0
    undecided.published(2, 0.01)
    # Until the oldest would expire
    assert undecided.wait_s(0.1, 2, 0.5) == pytest.approx(0.4)
    undecided.decided(1)
    assert len(undecided) == 1 and undecided.wait_s(0.1, 2, 0.5) == 0.0


def test_limit_0_never_waits():
    undecided = UndecidedMatches()
    for stamp in range(5):
        undecided.published(stamp, 0.0)
    assert undecided.wait_s(0.0, 0, 0.5) == 0.0


def test_a_decision_forgets_the_earlier_matches_and_an_unknown_one_nothing():
    undecided = UndecidedMatches()
    for stamp in (10, 20, 30):
        undecided.published(stamp, 0.0)
    undecided.decided(99)  # not ours (another run, a pair matched before a restart)
    assert len(undecided) == 3
    undecided.decided(20)  # decisions come in order: 10's was lost
    assert len(undecided) == 1
    assert undecided.wait_s(0.0, 1, 0.5) > 0.0
    assert undecided.expired == 0


def test_matches_without_a_decision_expire_and_are_counted():
    undecided = UndecidedMatches()
    undecided.published(1, 0.0)
    undecided.published(2, 0.3)
    assert undecided.wait_s(0.6, 1, 0.5) > 0.0  # 1 expired, 2 not yet
    assert undecided.expired == 1 and len(undecided) == 1
    assert undecided.wait_s(0.9, 1, 0.5) == 0.0
    assert undecided.expired == 2 and len(undecided) == 0
