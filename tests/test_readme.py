"""The README documents every node's parameters exactly as the code declares them."""

import importlib.util
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]


def _tables_module():
    spec = importlib.util.spec_from_file_location(
        'parameter_tables', REPO_ROOT / 'scripts' / 'parameter_tables.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_node_has_a_parameter_table_in_the_readme():
    tables = _tables_module()
    readme = (REPO_ROOT / 'README.md').read_text()
    documented = {match.group('node') for match in tables.BLOCK.finditer(readme)}
    assert documented == set(tables.NODE_PARAMETER_MODULES), (
        'README.md parameter blocks differ from the nodes: '
        f'missing {set(tables.NODE_PARAMETER_MODULES) - documented}, '
        f'unknown {documented - set(tables.NODE_PARAMETER_MODULES)}')


def test_readme_parameter_tables_match_the_declared_defaults():
    tables = _tables_module()
    for path in tables.READMES:
        readme = path.read_text()
        assert tables.rewrite_readme(readme) == readme, (
            f'{path.relative_to(REPO_ROOT)} parameter tables are stale: run '
            'python scripts/parameter_tables.py --write')


def test_node_config_files_hold_the_declared_defaults():
    import yaml

    tables = _tables_module()
    packages = {'stereo_fuzzy_perception': 'src/stereo_fuzzy_perception/config',
                'cartesian_3p_driver': 'src/cartesian_3p_driver/config'}
    for node, module_name in tables.NODE_PARAMETER_MODULES.items():
        config_dir = REPO_ROOT / packages[module_name.split('.')[0]]
        config_file = config_dir / f'{node}.yaml'
        if not config_file.exists():
            continue
        specs = importlib.import_module(module_name).PARAMETERS
        declared = {spec.name: spec.default for spec in specs}
        values = yaml.safe_load(config_file.read_text())[node]['ros__parameters']
        flat = _flatten(values)
        for name, value in flat.items():
            assert name in declared, f'{config_file.name}: {name} is not a parameter of {node}'
            assert value == declared[name], (
                f'{config_file.name}: {name} = {value!r} but the declared default is '
                f'{declared[name]!r}')


def _flatten(values: dict, prefix: str = '') -> dict:
    flat = {}
    for key, value in values.items():
        if isinstance(value, dict):
            flat.update(_flatten(value, f'{prefix}{key}.'))
        else:
            flat[f'{prefix}{key}'] = value
    return flat
