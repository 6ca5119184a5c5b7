"""Message types by name: rosbags typestores with this project's types, and rclpy classes.

A bag needs each type's full definition (and its RIHS01 hash); rosbags knows the standard Jazzy
types and learns the others from .msg files. These are found where colcon installs them
(`<prefix>/share/<package>/msg/<Type>.msg` for every prefix on AMENT_PREFIX_PATH, and the
Python environment's own prefix) and, as a fallback, in this repository's interface packages.

ROS-free at import time: rclpy message modules are only imported by import_message_class().
"""

from __future__ import annotations

import importlib
import os
import re
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

_REPO_INTERFACES = Path(__file__).resolve().parents[3]  # src/
_TYPE_NAME = re.compile(r'^(?P<package>\w+)/(?P<kind>msg|srv|action)/(?P<name>\w+)$')


class MessageTypeError(LookupError):
    """A message type that cannot be found, with where it was looked for."""


def split_type_name(type_name: str) -> tuple[str, str, str]:
    """Split 'pkg/msg/Type' into (pkg, 'msg', Type).

    Raises:
        MessageTypeError: When the name is not of that form.
    """
    match = _TYPE_NAME.match(type_name)
    if not match:
        raise MessageTypeError(f'message type {type_name!r} is not of the form pkg/msg/Type')
    return match['package'], match['kind'], match['name']


def interface_search_paths() -> list[Path]:
    """Return the share directories searched for .msg files, in order."""
    prefixes = [Path(p) for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    prefixes.append(Path(sys.prefix))
    paths = [prefix / 'share' for prefix in prefixes]
    paths.append(_REPO_INTERFACES)
    return paths


def find_msg_file(type_name: str) -> Path | None:
    """Return the .msg file defining `type_name`, or None."""
    package, kind, name = split_type_name(type_name)
    for share in interface_search_paths():
        candidate = share / package / kind / f'{name}.msg'
        if candidate.is_file():
            return candidate
    return None


def _referenced_types(field_type: tuple[Any, Any]) -> set[str]:
    """Return the message types a parsed rosbags field type refers to."""
    kind, detail = field_type
    if kind == Nodetype.NAME:
        return {detail}
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        return _referenced_types(detail[0])
    return set()


def register_types(typestore: Typestore, type_names: Iterable[str]) -> None:
    """Teach `typestore` every type in `type_names` (and their field types) it does not know.

    Raises:
        MessageTypeError: When a definition cannot be found.
    """
    pending = [name for name in type_names if name not in typestore.fielddefs]
    new_types: dict[str, Any] = {}
    seen: set[str] = set()
    while pending:
        type_name = pending.pop()
        if type_name in seen or type_name in typestore.fielddefs:
            continue
        seen.add(type_name)
        path = find_msg_file(type_name)
        if path is None:
            raise MessageTypeError(
                f'no definition of {type_name} found under '
                + ', '.join(str(p) for p in interface_search_paths()))
        parsed = get_types_from_msg(path.read_text(), type_name)
        new_types.update(parsed)
        for _, fields in parsed.values():
            for _, field_type in fields:
                pending.extend(_referenced_types(field_type) - seen)
    if new_types:
        typestore.register(new_types)


def project_typestore(type_names: Iterable[str] = ()) -> Typestore:
    """Return a Jazzy typestore that also knows `type_names` (e.g. stereo_fuzzy_msgs types)."""
    typestore = get_typestore(Stores.ROS2_JAZZY)
    register_types(typestore, type_names)
    return typestore


def import_message_class(type_name: str) -> type:
    """Import the rclpy message class of 'pkg/msg/Type' (the workspace must be sourced).

    Raises:
        MessageTypeError: When the package or the type cannot be imported.
    """
    package, kind, name = split_type_name(type_name)
    try:
        module = importlib.import_module(f'{package}.{kind}')
        message_class: type = getattr(module, name)
        return message_class
    except (ImportError, AttributeError) as error:
        raise MessageTypeError(f'cannot import {type_name} ({error}); is the workspace '
                               'that defines it sourced?') from None
