"""Fuzzy rule bases of the best-point stage, as data: load, validate, write. ROS-free.

A rule base file (YAML) holds:

    name: chapter
    description: free text
    height_offset_m: 0.0            # added to the top height (step 6); fitted, or 0
    membership_functions:           # triangular, over r = d1 / d2
      - {name: less, points: [a, b, c]}        # a <= b <= c; a == b: left shoulder,
      - ...                                    #               b == c: right shoulder
    rules:
      - name: area1_greater
        area: 1                     # whose ratio r_k is the premise (1..4, Fig. 4)
        if: greater                 # a membership function name
        then:
          areas: [1, 2]             # consequent: the centre of the union of these areas
          offset_m: [0, 0, 0]       # plus this offset in `world` [m] (optional, default 0)

Loading checks everything and raises RuleBaseError naming the bad entry.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from stereo_fuzzy_perception.core.yaml_file import read_yaml_file

PACKAGED_RULE_BASES = {'fuzzy_chapter': 'fuzzy_chapter.yaml', 'fuzzy_fitted': 'fuzzy_fitted.yaml'}
"""The packaged rule base file of each fuzzy selector."""


class RuleBaseError(ValueError):
    """A rule base file that cannot be used; the message names the file and the bad entry."""


@dataclass(frozen=True)
class TriangularTerm:
    """A triangular membership function (simpful's semantics for shoulders).

    Attributes:
        name: Linguistic term (less, equal, greater).
        a: Left foot.
        b: Peak.
        c: Right foot; a == b makes a left shoulder (1 below b), b == c a right shoulder.
    """

    name: str
    a: float
    b: float
    c: float


@dataclass(frozen=True)
class FuzzyRule:
    """IF r_area IS term THEN the point is the centre of `consequent_areas` plus `offset_m`.

    Attributes:
        name: Rule name (reported in decisions).
        area: Area whose ratio is the premise (1..4).
        term: Membership function name of the premise.
        consequent_areas: Areas (1..4) whose union's centre is the consequent's base point.
        offset_m: (dx, dy, dz) added to the base point in `world` [m].
    """

    name: str
    area: int
    term: str
    consequent_areas: tuple[int, ...]
    offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class RuleBase:
    """Membership functions and rules of one fuzzy best-point system.

    Attributes:
        name: Rule base name (reported in decisions).
        description: What it is and where it came from.
        terms: The membership functions.
        rules: The rules, in file order (the order of decision arrays).
        height_offset_m: Added to the top height of step 6 [m].
    """

    name: str
    description: str
    terms: tuple[TriangularTerm, ...]
    rules: tuple[FuzzyRule, ...]
    height_offset_m: float = 0.0

    def term(self, name: str) -> TriangularTerm:
        """Return the membership function called `name`."""
        for term in self.terms:
            if term.name == name:
                return term
        raise KeyError(name)


def _fail(source: str, where: str, what: str) -> RuleBaseError:
    return RuleBaseError(f'{source}: {where}: {what}')


def _number(value: Any, source: str, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(
            float(value)):
        raise _fail(source, where, f'{value!r} is not a finite number')
    return float(value)


def rule_base_from_dict(data: Any, source: str = '<dict>') -> RuleBase:
    """Build and validate a rule base from parsed YAML.

    Args:
        data: The parsed document.
        source: Where it came from, for error messages.

    Returns:
        The rule base.

    Raises:
        RuleBaseError: Naming the bad entry and what was expected.
    """
    if not isinstance(data, dict):
        raise _fail(source, 'document', f'expected a mapping, got {type(data).__name__}')
    for key in ('name', 'membership_functions', 'rules'):
        if key not in data:
            raise _fail(source, 'document', f'missing key {key!r}')
    unknown = set(data) - {'name', 'description', 'height_offset_m', 'membership_functions',
                           'rules'}
    if unknown:
        raise _fail(source, 'document', f'unknown key(s) {", ".join(sorted(unknown))}')
    terms: list[TriangularTerm] = []
    raw_terms = data['membership_functions']
    if not isinstance(raw_terms, list) or not raw_terms:
        raise _fail(source, 'membership_functions', 'expected a non-empty list')
    for index, entry in enumerate(raw_terms):
        where = f'membership_functions[{index}]'
        if not isinstance(entry, dict) or 'name' not in entry or 'points' not in entry:
            raise _fail(source, where, 'expected {name: ..., points: [a, b, c]}')
        where = f'membership function {entry["name"]!r}'
        points = entry['points']
        if not isinstance(points, list) or len(points) != 3:
            raise _fail(source, where, f'points {points!r}: expected three break points')
        a, b, c = (_number(value, source, where) for value in points)
        if not a <= b <= c or a == c:
            raise _fail(source, where, f'break points {a}, {b}, {c} must satisfy a <= b <= c '
                                       'with a < c')
        if any(term.name == entry['name'] for term in terms):
            raise _fail(source, where, 'defined twice')
        terms.append(TriangularTerm(str(entry['name']), a, b, c))
    names = {term.name for term in terms}
    rules: list[FuzzyRule] = []
    raw_rules = data['rules']
    if not isinstance(raw_rules, list) or not raw_rules:
        raise _fail(source, 'rules', 'expected a non-empty list')
    for index, entry in enumerate(raw_rules):
        where = f'rules[{index}]'
        if not isinstance(entry, dict):
            raise _fail(source, where, 'expected a mapping')
        where = f'rule {entry.get("name", index)!r}'
        missing = [key for key in ('name', 'area', 'if', 'then') if key not in entry]
        if missing:
            raise _fail(source, where, f'missing key(s) {", ".join(missing)}')
        area = entry['area']
        if area not in (1, 2, 3, 4) or isinstance(area, bool):
            raise _fail(source, where, f'area {area!r} is not one of 1, 2, 3, 4')
        if entry['if'] not in names:
            raise _fail(source, where, f'premise term {entry["if"]!r} is not a membership '
                                       f'function ({", ".join(sorted(names))})')
        then = entry['then']
        if not isinstance(then, dict) or 'areas' not in then:
            raise _fail(source, where, 'then: expected {areas: [...], offset_m: [dx, dy, dz]}')
        areas = then['areas']
        if (not isinstance(areas, list) or not areas
                or any(k not in (1, 2, 3, 4) or isinstance(k, bool) for k in areas)
                or len(set(areas)) != len(areas)):
            raise _fail(source, where, f'then.areas {areas!r}: expected distinct areas 1..4')
        offset = then.get('offset_m', [0.0, 0.0, 0.0])
        if not isinstance(offset, list) or len(offset) != 3:
            raise _fail(source, where, f'then.offset_m {offset!r}: expected [dx, dy, dz] [m]')
        dx, dy, dz = (_number(value, source, where + ' then.offset_m') for value in offset)
        if any(rule.name == entry['name'] for rule in rules):
            raise _fail(source, where, 'defined twice')
        rules.append(FuzzyRule(str(entry['name']), int(area), str(entry['if']),
                               tuple(int(k) for k in areas), (dx, dy, dz)))
    height = _number(data.get('height_offset_m', 0.0), source, 'height_offset_m')
    return RuleBase(str(data['name']), str(data.get('description', '')), tuple(terms),
                    tuple(rules), height)


def rule_base_to_dict(rule_base: RuleBase) -> dict[str, Any]:
    """Return the YAML-ready form of a rule base (what rule_base_from_dict reads)."""
    return {
        'name': rule_base.name,
        'description': rule_base.description,
        'height_offset_m': rule_base.height_offset_m,
        'membership_functions': [{'name': term.name, 'points': [term.a, term.b, term.c]}
                                 for term in rule_base.terms],
        'rules': [{'name': rule.name, 'area': rule.area, 'if': rule.term,
                   'then': {'areas': list(rule.consequent_areas),
                            'offset_m': [float(value) for value in rule.offset_m]}}
                  for rule in rule_base.rules],
    }


def load_rule_base(path: str | Path) -> RuleBase:
    """Load and validate a rule base file.

    Raises:
        RuleBaseError: When the file is missing, not YAML, or has a bad entry.
    """
    path = Path(path)
    data = read_yaml_file(path, RuleBaseError, 'the rule base file')
    return rule_base_from_dict(data, str(path))


def save_rule_base(rule_base: RuleBase, path: str | Path, header: str = '') -> None:
    """Write a rule base file, with `header` as leading comment lines."""
    comment = ''.join(f'# {line}\n' if line else '#\n' for line in header.splitlines())
    body = yaml.safe_dump(rule_base_to_dict(rule_base), sort_keys=False,
                          default_flow_style=None, width=99)
    Path(path).write_text(comment + body)


def data_path(file_name: str) -> Path:
    """Return the path of a file in the package's data directory."""
    return Path(str(resources.files('stereo_fuzzy_perception').joinpath('data', file_name)))


def packaged_rule_base(selector: str) -> RuleBase:
    """Load the packaged rule base of a fuzzy selector (fuzzy_chapter or fuzzy_fitted).

    Raises:
        RuleBaseError: For a selector without a packaged rule base or a bad file.
    """
    if selector not in PACKAGED_RULE_BASES:
        raise RuleBaseError(f'selector {selector!r} has no packaged rule base (known: '
                            f'{", ".join(PACKAGED_RULE_BASES)})')
    return load_rule_base(data_path(PACKAGED_RULE_BASES[selector]))
