"""Split the chain's latency of each pair into stages, and say which stages made the tail.

ROS-free: the inputs are the per-pair timing values the nodes publish
(stereo_fuzzy_perception/nodes/pair_timing.py: `<event> [ns]`, `<step> [ms]`, `cpu [ms]`,
`gc [ms]`, text notes) as plain dicts, and the time the decision reached the benchmark.

The stages of one pair follow each other, so they add up to its latency (stamp -> decision):

  camera topics -> sync     the four input messages through DDS into stereo_sync_node
  sync                      pairing, checks and publishing the StereoPair
  pair -> correlation       DDS transfer of the pair into correlation_node's callback
  correlation queue         waiting for the worker (the previous pair still being matched)
  correlation work          decode ... publish matches; its steps and waits are listed under it
  fuzzy queue               the matches waited while fuzzy_best_point_node still decided earlier
                            pairs (its callback runs one message at a time)
  matches -> fuzzy          the rest of StereoMatches' way into fuzzy_best_point_node's callback
                            (DDS transfer, the take and its deserialisation)
  fuzzy work                decode, decide, publish
  decision -> benchmark     DDS transfer of the decision

Under each node's work: its steps, `waiting` (wall time minus the thread's CPU time: the
thread waited for a core, the GIL or a lock) and `gc` (the process's garbage collections).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

SYNC, CORRELATION, FUZZY = 'stereo_sync_node', 'correlation_node', 'fuzzy_best_point_node'
NODES = (SYNC, CORRELATION, FUZZY)

STAGES = ('camera topics -> sync', 'sync', 'pair -> correlation', 'correlation queue',
          'correlation work', 'fuzzy queue', 'matches -> fuzzy', 'fuzzy work',
          'decision -> benchmark')
CORRELATION_STEPS = ('decode', 'plan', 'rectify', 'match', 'triangulate', 'region',
                     'regions from matches', 'pack', 'publish matches')
PIPELINE_PARTS = ('rectify', 'match', 'triangulate', 'region')
FUZZY_STEPS = ('decode', 'decide', 'publish')
WORK_OF = {'correlation work': ('correlation', CORRELATION_STEPS),
           'fuzzy work': ('fuzzy', FUZZY_STEPS)}


@dataclass
class PairStages:
    """One pair's latency split into stages [ms]."""

    stamp_ns: int
    total_ms: float
    stages: dict[str, float]  # STAGES, in order; they add up to total_ms
    steps: dict[str, float]  # '<node> <step>', '<node> waiting', '<node> gc'
    notes: dict[str, str] = field(default_factory=dict)


def _ns(values: Mapping[str, str], event: str) -> int:
    return int(values[f'{event} [ns]'])


def _ms(values: Mapping[str, str], step: str) -> float:
    return float(values.get(f'{step} [ms]', 0.0))


def fuzzy_free_times(fuzzy: Mapping[int, Mapping[str, str]]) -> dict[int, int]:
    """Return, for each pair the fuzzy node timed, when it finished the pairs before it [ns].

    Args:
        fuzzy: fuzzy_best_point_node's timing values by pair stamp.
    """
    spans = sorted((int(values['in [ns]']), int(values['out [ns]']), stamp)
                   for stamp, values in fuzzy.items()
                   if 'in [ns]' in values and 'out [ns]' in values)
    free, busy_until = {}, 0
    for _in_ns, out, stamp in spans:
        free[stamp] = busy_until
        busy_until = max(busy_until, out)
    return free


def pair_stages(stamp_ns: int, arrival_ns: int, timing: Mapping[str, Mapping[str, str]],
                fuzzy_free_ns: int = 0) -> PairStages | None:
    """Return the stages of one pair, or None when a node's timing of it is missing.

    Args:
        stamp_ns: The pair's stamp [ns] (CLOCK_REALTIME when it was published).
        arrival_ns: When its decision reached the benchmark [ns].
        timing: Each node's timing values of the pair, by node name (NODES).
        fuzzy_free_ns: When the fuzzy node finished the pairs before this one [ns]
            (fuzzy_free_times; 0 = unknown: no queue is split off the transfer).
    """
    if any(node not in timing for node in NODES):
        return None
    sync, correlation, fuzzy = (timing[node] for node in NODES)
    try:
        matches_out, fuzzy_in = _ns(correlation, 'matches out'), _ns(fuzzy, 'in')
        queued_until = min(max(fuzzy_free_ns, matches_out), fuzzy_in)
        events = [stamp_ns, _ns(sync, 'in'), _ns(sync, 'out'), _ns(correlation, 'in'),
                  _ns(correlation, 'start'), matches_out, queued_until, fuzzy_in,
                  _ns(fuzzy, 'out'), arrival_ns]
    except (KeyError, ValueError):
        return None
    stages = {name: (later - earlier) * 1e-6
              for name, earlier, later in zip(STAGES, events[:-1], events[1:], strict=True)}
    steps: dict[str, float] = {}
    for node, prefix, names in ((correlation, 'correlation', CORRELATION_STEPS),
                                (fuzzy, 'fuzzy', FUZZY_STEPS)):
        for name in names:
            steps[f'{prefix} {name}'] = _ms(node, name)
        wall = (_ns(node, 'out') - _ns(node, 'start')) * 1e-6
        steps[f'{prefix} waiting'] = max(0.0, wall - _ms(node, 'cpu'))
        steps[f'{prefix} gc'] = _ms(node, 'gc')
    # The pipeline step holds rectify, match, triangulate and a failed region's first try;
    # what is left of it (checks, copies of the image part read) is counted as its own step.
    steps['correlation pipeline other'] = max(
        0.0, _ms(correlation, 'pipeline') - sum(_ms(correlation, part)
                                                for part in PIPELINE_PARTS))
    notes = {'matched': correlation.get('matched', '?'), 'status': fuzzy.get('status', '?'),
             'points': correlation.get('points', '?')}
    return PairStages(stamp_ns, (arrival_ns - stamp_ns) * 1e-6, stages, steps, notes)


def percentile(values: Sequence[float], q: float) -> float:
    """Return the q-th percentile (linear interpolation), NaN for no values."""
    return float(np.percentile(values, q)) if len(values) else float('nan')


@dataclass
class TailPair:
    """A pair above the latency percentile, and what made it slow."""

    pair: PairStages
    slowest_stage: str  # the stage furthest above its median
    excess_ms: dict[str, float]  # stages and steps, [ms] above their medians, largest first


def tail_pairs(pairs: Sequence[PairStages], q: float = 99.0) -> list[TailPair]:
    """Return the pairs whose latency is above the q-th percentile, slowest first.

    Each pair's stages and steps are compared with their medians over all pairs: the stage
    with the largest excess made it slow.
    """
    if not pairs:
        return []
    medians = {name: percentile([p.stages[name] for p in pairs], 50) for name in STAGES}
    step_medians = {name: percentile([p.steps[name] for p in pairs], 50)
                    for name in pairs[0].steps}
    limit = percentile([p.total_ms for p in pairs], q)
    result = []
    for pair in sorted(pairs, key=lambda p: -p.total_ms):
        if pair.total_ms <= limit:
            break
        excess = {name: pair.stages[name] - medians[name] for name in STAGES}
        excess.update({name: pair.steps[name] - step_medians[name] for name in step_medians})
        slowest = max(STAGES, key=lambda name: excess[name])
        result.append(TailPair(pair, slowest, dict(sorted(excess.items(),
                                                          key=lambda item: -item[1]))))
    return result


def breakdown_markdown(pairs: Sequence[PairStages], q: float = 99.0, listed: int = 12) -> str:
    """Return markdown tables: each stage's p50 / p99 / max, and the pairs above the q-th
    percentile with what made each slow (`listed` of them at most)."""
    if not pairs:
        return '\n(no pair has timing from every node: nothing to break down)\n'
    lines = [f'\n### Where the latency goes ({len(pairs)} pairs with timing from every node; '
             'stages add up to the total, steps are parts of the work above them)\n',
             '| stage / step | p50 [ms] | p99 [ms] | max [ms] |', '|---|---:|---:|---:|']

    def row(name: str, values: list[float]) -> str:
        return (f'| {name} | {percentile(values, 50):.1f} | {percentile(values, 99):.1f} '
                f'| {max(values):.1f} |')

    lines.append(row('**total (stamp -> decision)**', [p.total_ms for p in pairs]))
    for stage in STAGES:
        lines.append(row(stage, [p.stages[stage] for p in pairs]))
        if stage in WORK_OF:
            prefix, steps = WORK_OF[stage]
            names = [f'{prefix} {step}' for step in steps]
            if prefix == 'correlation':
                names.append('correlation pipeline other')
            names += [f'{prefix} waiting', f'{prefix} gc']
            lines += [row(f'&nbsp;&nbsp;{name}', [p.steps[name] for p in pairs])
                      for name in names]
    tail = tail_pairs(pairs, q)
    limit = percentile([p.total_ms for p in pairs], q)
    counts = Counter(item.slowest_stage for item in tail)
    matched = Counter(item.pair.notes['matched'] for item in tail)
    lines += [f'\n### The {len(tail)} pairs above the p{q:g} ({limit:.1f} ms): which stage was '
              'furthest above its median\n',
              '| stage | pairs |', '|---|---:|']
    lines += [f'| {stage} | {count} |' for stage, count in counts.most_common()]
    lines.append('\nWhere correlation_node matched them: '
                 + ', '.join(f'{where}: {count}' for where, count in matched.most_common()))
    lines += ['\n| total [ms] | matched | points | status | largest excesses over the '
              'medians [ms] |', '|---:|---|---:|---|---|']
    for item in tail[:listed]:
        excess = ', '.join(f'{name} +{ms:.1f}' for name, ms in list(item.excess_ms.items())[:4])
        notes = item.pair.notes
        lines.append(f'| {item.pair.total_ms:.1f} | {notes["matched"]} | {notes["points"]} '
                     f'| {notes["status"]} | {excess} |')
    return '\n'.join(lines) + '\n'
