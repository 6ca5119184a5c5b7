"""Test set-up shared by tests/ and each package's test/ folder.

Pure algorithm tests import the packages straight from src/, so they run without the workspace
sourced. Tests marked `ros` need `source scripts/env.sh` (scripts/test.sh does it); outside CI
they are skipped with a reason when rclpy or the built interfaces are missing, in CI they fail.
"""

import os
import sys
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parent
for path in ('.', 'src/stereo_fuzzy_parameters', 'src/stereo_fuzzy_perception',
             'src/cartesian_3p_driver', 'tests/support'):
    sys.path.insert(0, str(REPO_ROOT / path))


def _ros_missing() -> str | None:
    try:
        import rclpy  # noqa: F401

        import stereo_fuzzy_msgs.msg  # noqa: F401
    except ImportError as error:
        return f'ROS workspace not sourced ({error}); run scripts/test.sh'
    return None


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    reason = _ros_missing()
    if reason is None or os.environ.get('CI'):
        return
    skip = pytest.mark.skip(reason=reason)
    for item in items:
        if 'ros' in item.keywords or 'system' in item.keywords:
            item.add_marker(skip)


pytest_plugins = ['ros_fixtures', 'gantry_harness']
