"""Reading the package's YAML files with errors that name the file. ROS-free."""

from __future__ import annotations

from pathlib import Path

import yaml


def read_yaml_file(path: Path, error_type: type[Exception], what: str) -> object:
    """Return the parsed document of `path` (any YAML value).

    Raises:
        error_type: When the file cannot be read (`{path}: cannot read {what} (...)`) or is not
            valid YAML (`{path}: not valid YAML (...)`).
    """
    try:
        text = path.read_text()
    except OSError as error:
        raise error_type(f'{path}: cannot read {what} ({error})') from error
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as error:
        raise error_type(f'{path}: not valid YAML ({error})') from error
