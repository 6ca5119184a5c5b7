"""Fuzzification, rules and Eq. 10 defuzzification of the best-point system. ROS-free.

Each rule has one premise, `r_k is term`, so its firing strength w_l is the membership degree of
r_k in that term. Its consequent is a crisp point y_l: the centre of the union of some areas plus a
constant offset (a zero-order Takagi-Sugeno consequent). Eq. 10, the centre of gravity of the
singletons, gives the point: y* = sum(y_l w_l) / sum(w_l), per coordinate.

Hand-written on purpose: twelve rules take a few microseconds, and the same arrays serve the
decision message and the least-squares fit of the consequents (`normalized_firing_strengths`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from stereo_fuzzy_perception.core.best_point.four_areas import FourAreas
from stereo_fuzzy_perception.core.best_point.rule_base import RuleBase, TriangularTerm


def triangular_degree(x: np.ndarray | float, term: TriangularTerm) -> np.ndarray:
    """Return the membership degree of x in a triangular term (0..1, same shape as x).

    Semantics as simpful's Triangular_MF: rising from a to b, falling from b to c, zero
    outside [a, c]; a == b is a left shoulder (1 for x <= b), b == c a right shoulder. NaN
    inputs give 0.
    """
    x = np.asarray(x, dtype=float)
    with np.errstate(invalid='ignore', divide='ignore'):
        rising = np.ones_like(x) if term.a == term.b else (x - term.a) / (term.b - term.a)
        falling = np.ones_like(x) if term.b == term.c else (term.c - x) / (term.c - term.b)
        degree = np.where(x < term.b, rising, falling)
    membership: np.ndarray = np.nan_to_num(np.clip(degree, 0.0, 1.0), nan=0.0)
    return membership


@dataclass(frozen=True)
class _RuleArrays:
    """A rule base as index arrays, so one inference is a few whole-array operations.

    Attributes:
        premise_term: (L,) index into the rule base's terms of each rule's premise.
        premise_area: (L,) 0..3: the area whose ratio is the premise.
        consequent_areas: (L, 4) 1.0 where the area belongs to the rule's consequent union.
        offsets: (L, 3) consequent offsets [m].
    """

    premise_term: np.ndarray
    premise_area: np.ndarray
    consequent_areas: np.ndarray
    offsets: np.ndarray


@functools.lru_cache(maxsize=16)
def _rule_arrays(rule_base: RuleBase) -> _RuleArrays:
    term_index = {term.name: index for index, term in enumerate(rule_base.terms)}
    consequent_areas = np.zeros((len(rule_base.rules), 4))
    for row, rule in enumerate(rule_base.rules):
        consequent_areas[row, np.asarray(rule.consequent_areas) - 1] = 1.0
    return _RuleArrays(np.array([term_index[rule.term] for rule in rule_base.rules]),
                       np.array([rule.area - 1 for rule in rule_base.rules]),
                       consequent_areas,
                       np.array([rule.offset_m for rule in rule_base.rules], dtype=float))


def membership_degrees(rule_base: RuleBase, ratios: np.ndarray) -> np.ndarray:
    """Return the premise degree of every rule, shape (..., L) for ratios of shape (..., 4)."""
    ratios = np.asarray(ratios, dtype=float)
    arrays = _rule_arrays(rule_base)
    by_term = np.stack([triangular_degree(ratios, term) for term in rule_base.terms],
                       axis=-2)  # (..., T, 4)
    degrees: np.ndarray = by_term[..., arrays.premise_term, arrays.premise_area]
    return degrees


def firing_strengths(degrees: np.ndarray, consequents: np.ndarray) -> np.ndarray:
    """Return w_l: the premise degree, or 0 for a rule whose consequent is undefined.

    A consequent is undefined (NaN) when all of its areas are empty; an empty premise area has
    a NaN ratio and so degree 0 already.
    """
    defined = np.all(np.isfinite(consequents), axis=-1)
    return np.where(defined, degrees, 0.0)


def normalized_firing_strengths(rule_base: RuleBase, ratios: np.ndarray,
                                consequents: np.ndarray | None = None) -> np.ndarray:
    """Return w_l / sum(w), shape (..., L); rows where no rule fires are all zero.

    Args:
        rule_base: The rules.
        ratios: (..., 4) r_k.
        consequents: (..., L, 3) consequent points; rules with NaN ones do not fire.
    """
    strengths = membership_degrees(rule_base, ratios)
    if consequents is not None:
        strengths = firing_strengths(strengths, consequents)
    total = strengths.sum(axis=-1, keepdims=True)
    with np.errstate(invalid='ignore', divide='ignore'):
        normalized = np.where(total > 0.0, strengths / total, 0.0)
    return np.asarray(normalized)


def consequent_base_points(rule_base: RuleBase, centres: np.ndarray,
                           counts: np.ndarray) -> np.ndarray:
    """Return each rule's base point (centre of its areas' union), shape (..., L, 3).

    Args:
        rule_base: The rules.
        centres: (..., 4, 3) area centres [m] (NaN for an empty area).
        counts: (..., 4) weight of each area (points, or FourAreas.weights).

    Returns:
        The weighted mean of the union's area centres; NaN when all of them are empty.
    """
    weights = (np.asarray(counts, dtype=float)[..., np.newaxis, :]
               * _rule_arrays(rule_base).consequent_areas)  # (..., L, 4)
    with np.errstate(invalid='ignore', divide='ignore'):
        bases: np.ndarray = ((weights @ np.nan_to_num(np.asarray(centres, dtype=float)))
                             / weights.sum(axis=-1, keepdims=True))
    return bases


@dataclass(frozen=True)
class FuzzyResult:
    """The outcome of one inference.

    Attributes:
        membership_degrees: (L,) degree of each rule's premise.
        firing_strengths: (L,) w_l of Eq. 10: the degree (one premise per rule), or 0 when
            the rule's consequent is undefined.
        consequent_points: (L, 3) y_l [m] in `world`.
        point: (3,) Eq. 10 point [m], or None when no rule fired (sum of w is 0).
    """

    membership_degrees: np.ndarray
    firing_strengths: np.ndarray
    consequent_points: np.ndarray
    point: np.ndarray | None


def infer(rule_base: RuleBase, areas: FourAreas) -> FuzzyResult:
    """Fuzzify the four ratios, fire the rules and defuzzify with Eq. 10.

    Args:
        rule_base: Membership functions and rules.
        areas: The four areas (status ok; an empty area's rules do not fire).

    Returns:
        Degrees, strengths, consequent points (NaN when all their areas are empty) and the
        Eq. 10 point (None if nothing fired).
    """
    degrees = membership_degrees(rule_base, areas.ratio)
    consequents = (consequent_base_points(rule_base, areas.centres, areas.weights)
                   + _rule_arrays(rule_base).offsets)
    strengths = firing_strengths(degrees, consequents)
    total = float(strengths.sum())
    point = None if total <= 0.0 else (strengths @ np.nan_to_num(consequents)) / total
    return FuzzyResult(degrees, strengths, consequents, point)
