"""Reading the package's data files safely, with errors that name the file. ROS-free.

Files named by parameters can be anything a peer on the ROS domain sets: a FIFO (whose open()
blocks until a writer appears), /dev/zero (endless), a directory, a huge file. Every file is
therefore opened non-blocking, must be a regular file, and is read up to a size cap, so a read
never blocks the executor and never grows the process beyond the cap.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

import yaml

MAX_DATA_FILE_BYTES = 16 * 1024 * 1024
"""Largest rule base, calibration or weights file read [bytes] (the packaged ones are < 20 kB)."""


def read_file_bytes(path: Path, error_type: type[Exception], what: str,
                    max_bytes: int = MAX_DATA_FILE_BYTES) -> bytes:
    """Return the contents of the regular file `path`, never blocking, at most `max_bytes`.

    Raises:
        error_type: When the file cannot be opened, is not a regular file (FIFO, device,
            directory, socket) or is larger than `max_bytes`; the message names the file.
    """
    try:
        descriptor = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, 'O_CLOEXEC', 0))
    except (OSError, ValueError) as error:  # ValueError: a NUL byte in the path
        raise error_type(f'{path}: cannot read {what} ({error})') from error
    try:
        info = os.fstat(descriptor)
        if not stat.S_ISREG(info.st_mode):
            raise error_type(f'{path}: cannot read {what}: not a regular file '
                             f'({_file_kind(info.st_mode)})')
        if info.st_size > max_bytes:
            raise error_type(f'{path}: cannot read {what}: {info.st_size} bytes, more than '
                             f'the {max_bytes} allowed')
        chunks = []
        size = 0
        while size <= max_bytes:  # the file may grow while it is read
            chunk = os.read(descriptor, min(1 << 20, max_bytes + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
        if size > max_bytes:
            raise error_type(f'{path}: cannot read {what}: grew beyond the {max_bytes} bytes '
                             'allowed while being read')
        return b''.join(chunks)
    except OSError as error:
        raise error_type(f'{path}: cannot read {what} ({error})') from error
    finally:
        os.close(descriptor)


def _file_kind(mode: int) -> str:
    kinds = ((stat.S_ISDIR, 'a directory'), (stat.S_ISFIFO, 'a FIFO'),
             (stat.S_ISCHR, 'a character device'), (stat.S_ISBLK, 'a block device'),
             (stat.S_ISSOCK, 'a socket'))
    return next((name for test, name in kinds if test(mode)), 'not a regular file')


def read_yaml_file(path: Path, error_type: type[Exception], what: str) -> object:
    """Return the parsed document of `path` (any YAML value).

    Raises:
        error_type: When the file cannot be read (`{path}: cannot read {what} (...)`, see
            read_file_bytes) or is not valid YAML (`{path}: not valid YAML (...)`).
    """
    data = read_file_bytes(path, error_type, what)
    try:
        return yaml.safe_load(data)
    except (yaml.YAMLError, RecursionError, ValueError) as error:
        # RecursionError: pathologically nested documents; ValueError: e.g. bad timestamps.
        raise error_type(f'{path}: not valid YAML ({type(error).__name__}: '
                         f'{str(error)[:200]})') from error
