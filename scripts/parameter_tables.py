"""Print (or write into the package READMEs) the parameter table of every node, from its specs.

Each node's table sits between `<!-- parameters:NODE -->` and `<!-- /parameters -->` in its
package's README (README.md links to them); tests/test_readme.py fails when a table differs
from what this script generates, so the docs cannot drift from the declarations. Update them
with: python scripts/parameter_tables.py --write
"""

from __future__ import annotations

import argparse
import importlib
import re
import sys
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
for package_dir in ('src/stereo_fuzzy_parameters', 'src/stereo_fuzzy_perception',
                    'src/cartesian_3p_driver'):
    sys.path.insert(0, str(REPO_ROOT / package_dir))

# node name -> module holding its PARAMETERS list (generated from the node's settings type)
NODE_PARAMETER_MODULES = {
    'stereo_sync_node': 'stereo_fuzzy_perception.nodes.stereo_sync_parameters',
    'correlation_node': 'stereo_fuzzy_perception.nodes.correlation_parameters',
    'fuzzy_best_point_node': 'stereo_fuzzy_perception.nodes.fuzzy_best_point_parameters',
    'gantry_driver_node': 'cartesian_3p_driver.gantry_driver_parameters',
    'fake_gantry': 'cartesian_3p_driver.fake_gantry_parameters',
}


def package_readme(node: str) -> Path:
    """Return the README of the package that holds `node`: the one place of its table."""
    package = NODE_PARAMETER_MODULES[node].split('.')[0]
    return REPO_ROOT / 'src' / package / 'README.md'


# Every README that holds parameter blocks: the package READMEs.
READMES = tuple(sorted({package_readme(node) for node in NODE_PARAMETER_MODULES}))
BLOCK = re.compile(r'(<!-- parameters:(?P<node>\w+) -->\n)(?P<body>.*?)(<!-- /parameters -->)',
                   re.DOTALL)


def _format_default(value: object) -> str:
    if isinstance(value, str):
        return f"`'{value}'`" if value else "`''`"
    if isinstance(value, bool):
        return f'`{str(value).lower()}`'
    return f'`{value}`'


def parameter_table(node: str) -> str:
    """Return the markdown table of `node`'s parameters."""
    specs = importlib.import_module(NODE_PARAMETER_MODULES[node]).PARAMETERS
    lines = ['| parameter | default | allowed | description |', '|---|---|---|---|']
    for spec in specs:
        description = spec.description.replace('|', '\\|')
        allowed = spec.constraint_text().replace('|', '\\|')
        lines.append(f'| `{spec.name}` | {_format_default(spec.default)} | {allowed} | '
                     f'{description} |')
    return '\n'.join(lines) + '\n'


def rewrite_readme(text: str) -> str:
    """Return README text with every parameter block regenerated."""
    return BLOCK.sub(lambda match: match.group(1) + parameter_table(match.group('node'))
                     + match.group(4), text)


def main() -> None:
    """Print the tables, or rewrite the READMEs in place with --write."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--write', action='store_true', help='rewrite the READMEs in place')
    arguments = parser.parse_args()
    if arguments.write:
        for readme in READMES:
            readme.write_text(rewrite_readme(readme.read_text()))
        return
    for node in NODE_PARAMETER_MODULES:
        print(f'### {node}\n\n{parameter_table(node)}')


if __name__ == '__main__':
    main()
