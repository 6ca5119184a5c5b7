"""Fuzzification, rules and Eq. 10 defuzzification of the best-point system. ROS-free.

Each rule has one premise, `r_k is term`, so its firing strength w_l is the membership degree of
r_k in that term. Its consequent is a crisp point y_l: the centre of the union of some areas plus a
constant offset (a zero-order Takagi-Sugeno consequent). Eq. 10, the centre of gravity of the
singletons, gives the point: y* = sum(y_l w_l) / sum(w_l), per coordinate.

Hand-written on purpose: twelve rules take a few microseconds, and the same arrays serve the
decision message and the least-squares fit of the consequents (`normalized_firing_strengths`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .correlation_area import FourAreas
from .rule_base import RuleBase, TriangularTerm


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


def membership_degrees(rule_base: RuleBase, ratios: np.ndarray) -> np.ndarray:
    """Return the premise degree of every rule, shape (..., L) for ratios of shape (..., 4)."""
    ratios = np.asarray(ratios, dtype=float)
    by_term = {term.name: triangular_degree(ratios, term) for term in rule_base.terms}
    columns = [by_term[rule.term][..., rule.area - 1] for rule in rule_base.rules]
    return np.stack(columns, axis=-1)


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
        centres: (..., 4, 3) area centres [m].
        counts: (..., 4) points per area.
    """
    centres = np.asarray(centres, dtype=float)
    counts = np.asarray(counts, dtype=float)
    finite_centres = np.nan_to_num(centres)
    by_areas: dict[tuple[int, ...], np.ndarray] = {}
    with np.errstate(invalid='ignore', divide='ignore'):
        for areas in {rule.consequent_areas for rule in rule_base.rules}:
            index = np.asarray(areas) - 1
            weight = counts[..., index]
            total = weight.sum(axis=-1, keepdims=True)
            by_areas[areas] = np.einsum('...k,...kj->...j', weight,
                                        finite_centres[..., index, :]) / total
    return np.stack([by_areas[rule.consequent_areas] for rule in rule_base.rules], axis=-2)


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
    offsets = np.array([rule.offset_m for rule in rule_base.rules], dtype=float)
    consequents = consequent_base_points(rule_base, areas.centres, areas.counts) + offsets
    strengths = firing_strengths(degrees, consequents)
    total = float(strengths.sum())
    point = None if total <= 0.0 else (strengths @ np.nan_to_num(consequents)) / total
    return FuzzyResult(degrees, strengths, consequents, point)
