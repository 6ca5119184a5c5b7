"""ROS domain ids held by file locks, so concurrent tests and benchmarks never share a graph.

Each holder locks `<tmp>/stereo_fuzzy_ros_domains/<id>.lock`; the lock goes with the process,
so a crashed run frees its id. Ids 1..100 keep Fast DDS's port numbers inside the valid range.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import random
import tempfile
from collections.abc import Iterator
from pathlib import Path

DOMAIN_IDS = range(1, 101)
DOMAIN_LOCK_DIR = Path(tempfile.gettempdir()) / 'stereo_fuzzy_ros_domains'


class NoFreeDomainError(RuntimeError):
    """Every domain id in DOMAIN_IDS is held by another run."""


@contextlib.contextmanager
def reserved_domain_id() -> Iterator[int]:
    """Hold a domain id no other test or benchmark on this machine holds, while in the block.

    Raises:
        NoFreeDomainError: When all ids are held.
    """
    DOMAIN_LOCK_DIR.mkdir(exist_ok=True)
    candidates = list(DOMAIN_IDS)
    random.shuffle(candidates)
    for domain_id in candidates:
        lock_file = open(DOMAIN_LOCK_DIR / f'{domain_id}.lock', 'w')  # noqa: SIM115
        try:
            fcntl.flock(lock_file, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            lock_file.close()
            continue
        try:
            yield domain_id
        finally:
            fcntl.flock(lock_file, fcntl.LOCK_UN)
            lock_file.close()
        return
    raise NoFreeDomainError(
        f'all ROS domain ids {DOMAIN_IDS.start}..{DOMAIN_IDS.stop - 1} are in use')


@contextlib.contextmanager
def exported_domain_id() -> Iterator[int]:
    """Hold a free domain id (reserved_domain_id) and export it, with discovery kept on this
    host, to the processes this one starts: what a benchmark's chain runs in."""
    with reserved_domain_id() as domain_id:
        os.environ['ROS_DOMAIN_ID'] = str(domain_id)
        os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
        yield domain_id
