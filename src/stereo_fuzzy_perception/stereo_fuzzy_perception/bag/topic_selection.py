"""Which topics a play or record keeps, and topic remaps, as `ros2 bag play|record` takes them.

ROS-free: the standard library only.
"""

from __future__ import annotations

import re
from collections.abc import Iterable

from stereo_fuzzy_perception.bag.bag_format import BagError, absolute_topic


def select_topics(available: Iterable[str], topics: Iterable[str] | None = None,
                  regex: str | None = None, exclude_topics: Iterable[str] = (),
                  exclude_regex: str | None = None) -> tuple[str, ...]:
    """Return the topics of `available` that a selection keeps, in the order of `available`.

    As `ros2 bag play|record`: a topic is kept when it is named in `topics` or matches `regex`
    (everything when neither is given), and then dropped when it is in `exclude_topics` or
    matches `exclude_regex`. Names are made absolute; regexes match anywhere (re.search).

    Raises:
        BagError: For a regex that does not compile.
    """
    def compiled(pattern: str | None, option: str) -> re.Pattern[str] | None:
        if pattern is None:
            return None
        try:
            return re.compile(pattern)
        except re.error as error:
            raise BagError(f'{option} {pattern!r} is not a regular expression ({error})') \
                from None

    include = compiled(regex, '--regex')
    exclude = compiled(exclude_regex, '--exclude-regex')
    named = None if topics is None else {absolute_topic(name) for name in topics}
    excluded = {absolute_topic(name) for name in exclude_topics}
    kept = []
    for topic in available:
        wanted = (named is None and include is None) or (named is not None and topic in named) \
            or (include is not None and include.search(topic) is not None)
        if wanted and topic not in excluded and not (exclude and exclude.search(topic)):
            kept.append(topic)
    return tuple(kept)


def parse_remaps(rules: Iterable[str]) -> dict[str, str]:
    """Parse 'old:=new' rules into {old: new}, both made absolute.

    Raises:
        BagError: For a rule without ':=' or with an empty side.
    """
    remaps = {}
    for rule in rules:
        old, separator, new = rule.partition(':=')
        if not separator or not old.strip() or not new.strip():
            raise BagError(f'remap rule {rule!r} is not of the form old_topic:=new_topic')
        remaps[absolute_topic(old.strip())] = absolute_topic(new.strip())
    return remaps
