"""The package README's fuzzy_best_point_node section documents the declared parameters."""

import importlib.util
import re
from pathlib import Path

import yaml

PACKAGE_DIR = Path(__file__).resolve().parents[1]
REPO_ROOT = PACKAGE_DIR.parents[1]


def parameter_tables():
    spec = importlib.util.spec_from_file_location(
        'parameter_tables', REPO_ROOT / 'scripts' / 'parameter_tables.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_readme_parameter_table_matches_the_specs():
    readme = (PACKAGE_DIR / 'README.md').read_text()
    block = re.search(r'<!-- parameters:fuzzy_best_point_node -->\n(.*?)<!-- /parameters -->',
                      readme, re.DOTALL)
    assert block, 'no fuzzy_best_point_node parameter block in the package README'
    assert block.group(1) == parameter_tables().parameter_table('fuzzy_best_point_node'), (
        'the fuzzy_best_point_node table in the package README is stale: regenerate it with '
        "scripts/parameter_tables.py (parameter_table('fuzzy_best_point_node'))")


def test_config_file_holds_every_declared_default():
    from stereo_fuzzy_perception.nodes.fuzzy_best_point_parameters import PARAMETERS

    config = yaml.safe_load((PACKAGE_DIR / 'config' / 'fuzzy_best_point_node.yaml').read_text())
    values = config['fuzzy_best_point_node']['ros__parameters']

    def flatten(mapping, prefix=''):
        for key, value in mapping.items():
            if isinstance(value, dict):
                yield from flatten(value, f'{prefix}{key}.')
            else:
                yield f'{prefix}{key}', value

    flat = dict(flatten(values))
    assert flat == {spec.name: spec.default for spec in PARAMETERS}
