"""chain/latency_stages.py: a pair's latency split into stages that add up, and the tail."""

from __future__ import annotations

import pytest

from chain.latency_stages import (
    CORRELATION,
    FUZZY,
    STAGES,
    SYNC,
    breakdown_markdown,
    fuzzy_free_times,
    pair_stages,
    tail_pairs,
)

MS = 1_000_000


def timing(stamp: int, correlation_ms: float = 10.0, fuzzy_ms: float = 8.0,
           fuzzy_in_ms: float | None = None) -> dict[str, dict[str, str]]:
    """Return the three nodes' timing of a pair stamped `stamp` [ns] (events in ms after it)."""
    def node(events: dict[str, float], **values: str) -> dict[str, str]:
        return {**{f'{name} [ns]': str(stamp + int(ms * MS)) for name, ms in events.items()},
                **values}
    matches_out = 8.0 + correlation_ms
    fuzzy_in = matches_out + 1.0 if fuzzy_in_ms is None else fuzzy_in_ms
    return {
        SYNC: node({'in': 2.0, 'start': 2.0, 'out': 3.0}),
        CORRELATION: node({'in': 5.0, 'start': 6.0, 'matches out': matches_out,
                           'out': matches_out + 0.5},
                          **{'match [ms]': f'{correlation_ms - 4.0}', 'rectify [ms]': '1.0',
                             'pipeline [ms]': f'{correlation_ms - 2.0}', 'cpu [ms]': '5.0',
                             'gc [ms]': '0.0', 'matched': 'area', 'points': '100'}),
        FUZZY: node({'in': fuzzy_in, 'start': fuzzy_in, 'out': fuzzy_in + fuzzy_ms},
                    **{'decide [ms]': f'{fuzzy_ms - 1.0}', 'cpu [ms]': f'{fuzzy_ms}',
                       'status': 'ok'}),
    }


def test_the_stages_add_up_to_the_latency():
    stamp = 1_000 * MS
    stages = pair_stages(stamp, stamp + 40 * MS, timing(stamp))
    assert stages is not None
    assert list(stages.stages) == list(STAGES)
    assert sum(stages.stages.values()) == pytest.approx(stages.total_ms) == pytest.approx(40.0)
    assert stages.stages['correlation work'] == pytest.approx(12.0)
    assert stages.steps['correlation match'] == pytest.approx(6.0)
    assert stages.steps['correlation pipeline other'] == pytest.approx(1.0)
    assert stages.steps['correlation waiting'] == pytest.approx(12.5 - 5.0)
    assert stages.stages['fuzzy queue'] == 0.0


def test_a_pair_without_every_node_timing_is_left_out():
    stamp = 1_000 * MS
    partial = timing(stamp)
    del partial[FUZZY]
    assert pair_stages(stamp, stamp + 40 * MS, partial) is None
    partial = timing(stamp)
    del partial[CORRELATION]['matches out [ns]']
    assert pair_stages(stamp, stamp + 40 * MS, partial) is None


def test_waiting_for_the_fuzzy_node_to_finish_earlier_pairs_is_its_queue():
    first, second = 1_000 * MS, 1_010 * MS
    # The first pair's decision runs until first + 19 + 30 ms; the second's matches are out
    # at second + 18 ms = first + 28 ms and wait until the fuzzy node is free.
    fuzzy = {first: timing(first, fuzzy_ms=30.0)[FUZZY],
             second: timing(second, fuzzy_in_ms=40.0)[FUZZY]}
    free = fuzzy_free_times(fuzzy)
    assert free[first] == 0 and free[second] == first + 49 * MS
    stages = pair_stages(second, second + 60 * MS, timing(second, fuzzy_in_ms=40.0),
                         free[second])
    assert stages is not None
    assert stages.stages['fuzzy queue'] == pytest.approx(49.0 - 28.0)
    assert stages.stages['matches -> fuzzy'] == pytest.approx(40.0 - 39.0)
    assert sum(stages.stages.values()) == pytest.approx(60.0)


def test_the_tail_names_the_stage_furthest_above_its_median():
    pairs = []
    for index in range(200):
        stamp = (1_000 + 40 * index) * MS
        slow = index == 7
        stages = pair_stages(stamp, stamp + (80 if slow else 40) * MS,
                             timing(stamp, correlation_ms=50.0 if slow else 10.0))
        assert stages is not None
        pairs.append(stages)
    tail = tail_pairs(pairs, 99.0)
    assert tail and tail[0].pair is pairs[7]
    assert tail[0].slowest_stage == 'correlation work'
    assert 'correlation work' in breakdown_markdown(pairs)
