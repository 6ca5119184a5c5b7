"""The package README documents the parameters exactly as the specs declare (the config files:
tests/test_readme.py)."""

import importlib.util
from pathlib import Path

from cartesian_3p_driver.fake_gantry_parameters import PARAMETERS as FAKE_GANTRY
from cartesian_3p_driver.gantry_driver_parameters import PARAMETERS as DRIVER

PACKAGE = Path(__file__).resolve().parents[1]
REPO_ROOT = PACKAGE.parents[1]


def _tables():
    spec = importlib.util.spec_from_file_location(
        'parameter_tables', REPO_ROOT / 'scripts' / 'parameter_tables.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_readme_has_both_parameter_tables_matching_the_specs():
    tables = _tables()
    readme = (PACKAGE / 'README.md').read_text()
    nodes = {match.group('node') for match in tables.BLOCK.finditer(readme)}
    assert nodes == {'gantry_driver_node', 'fake_gantry'}
    assert tables.rewrite_readme(readme) == readme, (
        'src/cartesian_3p_driver/README.md parameter tables are stale: regenerate them with '
        "scripts/parameter_tables.py's rewrite_readme")
    for spec in DRIVER + FAKE_GANTRY:
        assert f'| `{spec.name}` |' in readme

