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


MAX_TERMS = 100
"""Most membership functions a rule base may define."""
MAX_RULES = 1000
"""Most rules a rule base may hold."""
MAX_OFFSET_M = 10.0
"""Largest |offset| of a consequent or of height_offset_m [m]: the workspace limits' range."""
MAX_BREAK_POINT = 1e6
"""Largest |break point| of a membership function over r = d1 / d2 [-]."""


def _fail(source: str, where: str, what: str) -> RuleBaseError:
    return RuleBaseError(f'{source}: {where}: {what}')


def _short(value: Any) -> str:
    """Return repr(value) cut to 60 characters, for messages about hostile files."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + '...'


def _number(value: Any, source: str, where: str, limit: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _fail(source, where, f'{_short(value)} is not a number')
    try:
        number = float(value)
    except OverflowError as error:  # an integer beyond the float range
        raise _fail(source, where, f'{_short(value)} is not a finite number') from error
    if not math.isfinite(number):
        raise _fail(source, where, f'{_short(value)} is not a finite number')
    if abs(number) > limit:
        raise _fail(source, where, f'{number:g} is beyond the allowed +-{limit:g}')
    return number


def _text(value: Any, source: str, where: str) -> str:
    if not isinstance(value, str) or not value:
        raise _fail(source, where, f'{_short(value)} is not a non-empty string')
    return value


def _mapping(value: Any, source: str, where: str, expected: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise _fail(source, where, f'expected {expected}, got {type(value).__name__}')
    odd = [key for key in value if not isinstance(key, str)]
    if odd:
        raise _fail(source, where, f'key {_short(odd[0])} is not a string')
    return value


def _area(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and 1 <= value <= 4


def rule_base_from_dict(data: Any, source: str = '<dict>') -> RuleBase:
    """Build and validate a rule base from parsed YAML.

    Every value is checked for type, finiteness and range before use, so any parsed YAML
    document gives either a usable rule base or a RuleBaseError, never another exception.

    Args:
        data: The parsed document.
        source: Where it came from, for error messages.

    Returns:
        The rule base.

    Raises:
        RuleBaseError: Naming the bad entry and what was expected.
    """
    data = _mapping(data, source, 'document', 'a mapping')
    for key in ('name', 'membership_functions', 'rules'):
        if key not in data:
            raise _fail(source, 'document', f'missing key {key!r}')
    unknown = set(data) - {'name', 'description', 'height_offset_m', 'membership_functions',
                           'rules'}
    if unknown:
        raise _fail(source, 'document', f'unknown key(s) {", ".join(sorted(unknown))}')
    name = _text(data['name'], source, 'name')
    description = data.get('description', '')
    if description is None:
        description = ''
    if not isinstance(description, str):
        raise _fail(source, 'description', f'{_short(description)} is not a string')
    terms = _terms(data['membership_functions'], source)
    rules = _rules(data['rules'], {term.name for term in terms}, source)
    height = _number(data.get('height_offset_m', 0.0), source, 'height_offset_m', MAX_OFFSET_M)
    return RuleBase(name, description, tuple(terms), tuple(rules), height)


def _terms(raw_terms: Any, source: str) -> list[TriangularTerm]:
    if not isinstance(raw_terms, list) or not raw_terms or len(raw_terms) > MAX_TERMS:
        raise _fail(source, 'membership_functions',
                    f'expected a non-empty list of at most {MAX_TERMS} membership functions')
    terms: list[TriangularTerm] = []
    for index, raw in enumerate(raw_terms):
        where = f'membership_functions[{index}]'
        entry = _mapping(raw, source, where, '{name: ..., points: [a, b, c]}')
        if set(entry) != {'name', 'points'}:
            raise _fail(source, where, 'expected exactly the keys name and points')
        name = _text(entry['name'], source, where + '.name')
        where = f'membership function {name!r}'
        points = entry['points']
        if not isinstance(points, list) or len(points) != 3:
            raise _fail(source, where, f'points {_short(points)}: expected three break points')
        a, b, c = (_number(value, source, where, MAX_BREAK_POINT) for value in points)
        if not a <= b <= c or a == c:
            raise _fail(source, where, f'break points {a}, {b}, {c} must satisfy a <= b <= c '
                                       'with a < c')
        if any(term.name == name for term in terms):
            raise _fail(source, where, 'defined twice')
        terms.append(TriangularTerm(name, a, b, c))
    return terms


def _rules(raw_rules: Any, names: set[str], source: str) -> list[FuzzyRule]:
    if not isinstance(raw_rules, list) or not raw_rules or len(raw_rules) > MAX_RULES:
        raise _fail(source, 'rules', f'expected a non-empty list of at most {MAX_RULES} rules')
    rules: list[FuzzyRule] = []
    for index, raw in enumerate(raw_rules):
        entry = _mapping(raw, source, f'rules[{index}]', 'a mapping')
        where = f'rule {_short(entry.get("name", index))}'
        missing = [key for key in ('name', 'area', 'if', 'then') if key not in entry]
        if missing:
            raise _fail(source, where, f'missing key(s) {", ".join(missing)}')
        unknown = set(entry) - {'name', 'area', 'if', 'then'}
        if unknown:
            raise _fail(source, where, f'unknown key(s) {", ".join(sorted(unknown))}')
        name = _text(entry['name'], source, f'rules[{index}].name')
        where = f'rule {name!r}'
        area = entry['area']
        if not _area(area):
            raise _fail(source, where, f'area {_short(area)} is not one of 1, 2, 3, 4')
        term = entry['if']
        if not isinstance(term, str) or term not in names:
            raise _fail(source, where, f'premise term {_short(term)} is not a membership '
                                       f'function ({", ".join(sorted(names))})')
        then = _mapping(entry['then'], source, where + ' then',
                        '{areas: [...], offset_m: [dx, dy, dz]}')
        if 'areas' not in then or not set(then) <= {'areas', 'offset_m'}:
            raise _fail(source, where, 'then: expected {areas: [...], offset_m: [dx, dy, dz]}')
        areas = then['areas']
        if (not isinstance(areas, list) or not areas or not all(_area(k) for k in areas)
                or len(set(areas)) != len(areas)):
            raise _fail(source, where,
                        f'then.areas {_short(areas)}: expected distinct areas 1..4')
        offset = then.get('offset_m', [0.0, 0.0, 0.0])
        if not isinstance(offset, list) or len(offset) != 3:
            raise _fail(source, where,
                        f'then.offset_m {_short(offset)}: expected [dx, dy, dz] [m]')
        dx, dy, dz = (_number(value, source, where + ' then.offset_m', MAX_OFFSET_M)
                      for value in offset)
        if any(rule.name == name for rule in rules):
            raise _fail(source, where, 'defined twice')
        rules.append(FuzzyRule(name, area, term, tuple(areas), (dx, dy, dz)))
    return rules


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
