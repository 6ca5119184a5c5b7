"""The READMEs document every node's parameters exactly as the code declares them, once, and
the config files set declared parameters only, to values other than their defaults."""

import importlib
import importlib.util
import re
from pathlib import Path

import pytest
import yaml

REPO_ROOT = Path(__file__).resolve().parents[1]
CONFIG_FILES = sorted(REPO_ROOT.glob('src/*/config/*.yaml')) + [
    REPO_ROOT / 'chain' / 'demo_params.yaml']


def _tables_module():
    spec = importlib.util.spec_from_file_location(
        'parameter_tables', REPO_ROOT / 'scripts' / 'parameter_tables.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_node_has_one_parameter_table_in_its_package_readme():
    tables = _tables_module()
    for node in tables.NODE_PARAMETER_MODULES:
        readme = tables.package_readme(node)
        blocks = [match for match in tables.BLOCK.finditer(readme.read_text())
                  if match.group('node') == node]
        assert len(blocks) == 1, (
            f'{readme.relative_to(REPO_ROOT)} holds {len(blocks)} parameter tables of {node}; '
            'it needs exactly one')
    for readme in tables.READMES:
        documented = {match.group('node') for match in tables.BLOCK.finditer(readme.read_text())}
        unknown = documented - set(tables.NODE_PARAMETER_MODULES)
        assert not unknown, f'{readme.relative_to(REPO_ROOT)} documents unknown nodes {unknown}'


def test_top_readme_links_to_the_tables_instead_of_repeating_them():
    tables = _tables_module()
    readme = (REPO_ROOT / 'README.md').read_text()
    assert not list(tables.BLOCK.finditer(readme)), 'README.md repeats a parameter table'
    for node in tables.NODE_PARAMETER_MODULES:
        package_readme = tables.package_readme(node)
        path = package_readme.relative_to(REPO_ROOT)
        anchors = re.findall(rf'\({re.escape(str(path))}#([\w-]+)\)', readme)
        sections = _sections_by_anchor(package_readme.read_text())
        linked = [anchor for anchor in anchors
                  if f'<!-- parameters:{node} -->' in sections.get(anchor, '')]
        assert len(linked) == 1, (
            f'README.md needs one link to the section of {path} holding the table of {node}; '
            f'it links to {anchors}')


def _sections_by_anchor(markdown: str) -> dict[str, str]:
    """Return each heading's section (up to the next heading), by its GitHub anchor."""
    sections = {}
    parts = re.split(r'^(#+ .*)$', markdown, flags=re.MULTILINE)
    for heading, body in zip(parts[1::2], parts[2::2], strict=True):
        title = heading.lstrip('#').strip().lower()
        anchor = re.sub(r'[^\w\- ]', '', title).replace(' ', '-')
        sections[anchor] = body
    return sections


def test_readme_parameter_tables_match_the_declared_defaults():
    tables = _tables_module()
    for path in tables.READMES:
        readme = path.read_text()
        assert tables.rewrite_readme(readme) == readme, (
            f'{path.relative_to(REPO_ROOT)} parameter tables are stale: run '
            'python scripts/parameter_tables.py --write')


@pytest.mark.parametrize('config_file', CONFIG_FILES,
                         ids=[str(path.relative_to(REPO_ROOT)) for path in CONFIG_FILES])
def test_config_files_set_declared_parameters_to_values_other_than_the_defaults(config_file):
    tables = _tables_module()
    document = yaml.safe_load(config_file.read_text())
    for node, section in document.items():
        assert node in tables.NODE_PARAMETER_MODULES, (
            f'{config_file.name}: {node} is not a node of this project')
        specs = importlib.import_module(tables.NODE_PARAMETER_MODULES[node]).PARAMETERS
        declared = {spec.name: spec.default for spec in specs}
        for name, value in _flatten(section['ros__parameters']).items():
            assert name in declared, f'{config_file.name}: {name} is not a parameter of {node}'
            assert value != declared[name], (
                f'{config_file.name}: {node} {name} = {value!r} is the default; config files '
                'hold only what differs from the defaults')


def _flatten(values: dict, prefix: str = '') -> dict:
    flat = {}
    for key, value in values.items():
        if isinstance(value, dict):
            flat.update(_flatten(value, f'{prefix}{key}.'))
        else:
            flat[f'{prefix}{key}'] = value
    return flat
