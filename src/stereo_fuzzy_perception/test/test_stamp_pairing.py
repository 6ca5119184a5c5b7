"""Stamp pairing: exact and approximate sets, each item used once, bounded queues (no ROS)."""

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from stereo_fuzzy_perception.core.stamp_pairing import (
    StampPairingError,
    StampSynchronizer,
    seconds_to_ns,
)

MS = 1_000_000  # [ns]


def feed(sync, arrivals):
    """Add (stream, stamp_ns, item) arrivals in order; return matched sets and evictions."""
    matched, evicted = [], []
    for stream, stamp, item in arrivals:
        result = sync.add(stream, stamp, item)
        if result.matched is not None:
            matched.append(result.matched)
        evicted.extend(result.evicted)
    return matched, evicted


def test_exact_pairing_matches_equal_stamps_only():
    sync = StampSynchronizer(2, slop_ns=0, queue_size=10)
    matched, _ = feed(sync, [
        (0, 100, 'L100'), (1, 101, 'R101'), (1, 100, 'R100'), (0, 200, 'L200'), (1, 200, 'R200'),
    ])
    assert [m.items for m in matched] == [('L100', 'R100'), ('L200', 'R200')]
    assert sync.queue_lengths() == (0, 1), 'R101 has no exact partner and must stay queued'


def test_four_streams_emit_when_every_stream_has_an_item_at_the_stamp():
    sync = StampSynchronizer(4, slop_ns=0)
    matched, _ = feed(sync, [(0, 5, 'li'), (1, 5, 'lc'), (2, 5, 'ri')])
    assert matched == []
    result = sync.add(3, 5, 'rc')
    assert result.matched is not None
    assert result.matched.items == ('li', 'lc', 'ri', 'rc')
    assert result.matched.stamps_ns == (5, 5, 5, 5)


def test_approximate_pairing_picks_the_closest_partner_within_slop():
    sync = StampSynchronizer(2, slop_ns=10 * MS)
    feed(sync, [(1, 91 * MS, 'R91'), (1, 103 * MS, 'R103'), (1, 108 * MS, 'R108'),
                (1, 130 * MS, 'R130')])
    result = sync.add(0, 105 * MS, 'L105')
    assert result.matched is not None
    assert result.matched.items == ('L105', 'R103')
    assert result.matched.span_ns == 2 * MS


def test_approximate_pairing_rejects_partners_beyond_slop():
    sync = StampSynchronizer(2, slop_ns=10 * MS)
    matched, _ = feed(sync, [(0, 0, 'L0'), (1, 11 * MS, 'R11')])
    assert matched == []
    matched, _ = feed(sync, [(1, 10 * MS, 'R10')])
    assert [m.items for m in matched] == [('L0', 'R10')], 'a span equal to the slop pairs'


def test_each_item_is_used_at_most_once():
    sync = StampSynchronizer(2, slop_ns=10 * MS)
    matched, _ = feed(sync, [(0, 0, 'L0'), (1, 1 * MS, 'R1'), (1, 2 * MS, 'R2')])
    assert [m.items for m in matched] == [('L0', 'R1')]
    assert sync.queue_lengths() == (0, 1), 'R2 must wait: L0 is already used'
    matched, _ = feed(sync, [(0, 3 * MS, 'L3')])
    assert [m.items for m in matched] == [('L3', 'R2')]


def test_bounded_queue_evicts_the_oldest_stamp():
    sync = StampSynchronizer(2, slop_ns=0, queue_size=2)
    matched, evicted = feed(sync, [(0, 3, 'L3'), (0, 1, 'L1'), (0, 2, 'L2')])
    assert matched == []
    assert [(e.stream, e.stamp_ns, e.item) for e in evicted] == [(0, 1, 'L1')]
    assert sync.queue_lengths() == (2, 0)
    matched, _ = feed(sync, [(1, 1, 'R1'), (1, 2, 'R2')])
    assert [m.items for m in matched] == [('L2', 'R2')], 'L1 was evicted and cannot pair'


def test_out_of_order_arrival_still_pairs():
    sync = StampSynchronizer(4, slop_ns=5 * MS)
    arrivals = [
        (0, 200 * MS, 'li200'), (2, 201 * MS, 'ri201'),
        (0, 100 * MS, 'li100'), (2, 102 * MS, 'ri102'),   # the older pair arrives late
        (3, 201 * MS, 'rc201'), (1, 100 * MS, 'lc100'), (3, 102 * MS, 'rc102'),
        (1, 200 * MS, 'lc200'),
    ]
    matched, evicted = feed(sync, arrivals)
    assert sorted(m.items for m in matched) == [
        ('li100', 'lc100', 'ri102', 'rc102'), ('li200', 'lc200', 'ri201', 'rc201')]
    assert evicted == []
    assert sync.queue_lengths() == (0, 0, 0, 0)


def test_four_streams_choose_the_tightest_set():
    # Left at 100 ms; the right camera has sets at 90 ms (span 10) and 104 ms (span 4).
    sync = StampSynchronizer(4, slop_ns=20 * MS)
    matched, _ = feed(sync, [(2, 90 * MS, 'ri90'), (2, 104 * MS, 'ri104'),
                              (3, 90 * MS, 'rc90'), (3, 104 * MS, 'rc104'),
                              (1, 100 * MS, 'lc'), (0, 100 * MS, 'li')])
    assert [m.items for m in matched] == [('li', 'lc', 'ri104', 'rc104')]


def test_changing_slop_and_queue_size_applies_to_the_next_add():
    sync = StampSynchronizer(2, slop_ns=0, queue_size=5)
    feed(sync, [(0, 0, 'L0'), (0, 1, 'L1'), (0, 2, 'L2')])
    sync.slop_ns = 3
    sync.queue_size = 1
    result = sync.add(1, 4, 'R4')
    assert result.matched is not None and result.matched.items == ('L2', 'R4')
    assert [e.item for e in result.evicted] == ['L0']
    assert sync.queue_lengths() == (1, 0)


@pytest.mark.parametrize(('arguments', 'named'), [
    ({'stream_count': 1}, 'stream_count=1'),
    ({'stream_count': 2, 'slop_ns': -1}, 'slop_ns=-1'),
    ({'stream_count': 2, 'queue_size': 0}, 'queue_size=0'),
])
def test_bad_set_up_is_named(arguments, named):
    with pytest.raises(StampPairingError, match=named):
        StampSynchronizer(**arguments)


def test_stream_out_of_range_is_named():
    with pytest.raises(StampPairingError, match='stream 2 is out of range'):
        StampSynchronizer(2).add(2, 0, 'x')


def test_seconds_to_ns_rounds():
    assert seconds_to_ns(0.02) == 20 * MS
    assert seconds_to_ns(1e-10) == 0


arrival = st.tuples(st.integers(0, 3), st.integers(0, 200 * MS))


@settings(max_examples=300, deadline=None)
@given(arrivals=st.lists(arrival, max_size=60), slop_ms=st.integers(0, 30),
       queue_size=st.integers(1, 8))
def test_property_no_item_used_twice_and_every_set_within_slop(arrivals, slop_ms, queue_size):
    sync = StampSynchronizer(4, slop_ns=slop_ms * MS, queue_size=queue_size)
    numbered = [(stream, stamp, (index, stream, stamp))
                for index, (stream, stamp) in enumerate(arrivals)]
    matched, evicted = feed(sync, numbered)
    used = [item for matched_set in matched for item in matched_set.items]
    assert len(used) == len(set(used)), 'an item appeared in two sets'
    for matched_set in matched:
        assert matched_set.span_ns <= slop_ms * MS
        assert [item[1] for item in matched_set.items] == [0, 1, 2, 3], 'one item per stream'
        assert [item[2] for item in matched_set.items] == list(matched_set.stamps_ns)
    evicted_items = {e.item for e in evicted}
    assert not evicted_items & set(used), 'an evicted item was also matched'
    assert all(length <= queue_size for length in sync.queue_lengths())
    # Conservation: every item is matched, evicted or still queued, exactly once.
    assert len(used) + len(evicted) + sum(sync.queue_lengths()) == len(arrivals)


@settings(max_examples=200, deadline=None)
@given(stamps=st.lists(st.integers(0, 10**12), min_size=1, max_size=30, unique=True),
       order=st.randoms(use_true_random=False))
def test_property_exact_pairs_match_whatever_the_arrival_order(stamps, order):
    sync = StampSynchronizer(2, slop_ns=0, queue_size=len(stamps))
    arrivals = [(stream, stamp, (stream, stamp)) for stamp in stamps for stream in (0, 1)]
    order.shuffle(arrivals)
    matched, evicted = feed(sync, arrivals)
    assert evicted == []
    assert sorted(m.stamps_ns for m in matched) == sorted((s, s) for s in stamps)
