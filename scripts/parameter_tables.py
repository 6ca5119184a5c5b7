"""Print (or write into the READMEs) the parameter table of every node, from the node's specs.

The tables sit between `<!-- parameters:NODE -->` and `<!-- /parameters -->` in README.md and in
the package READMEs; tests/test_readme.py fails when they differ from what this script
generates, so the docs cannot drift from the defaults. Update them with:
python scripts/parameter_tables.py --write
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

# node name -> module holding its PARAMETERS list
NODE_PARAMETER_MODULES = {
    'stereo_sync_node': 'stereo_fuzzy_perception.nodes.stereo_sync_parameters',
    'correlation_node': 'stereo_fuzzy_perception.nodes.correlation_parameters',
    'fuzzy_best_point_node': 'stereo_fuzzy_perception.nodes.fuzzy_best_point_parameters',
    'rig_transforms_node': 'stereo_fuzzy_perception.nodes.rig_transforms_parameters',
    'stereo_camera_node': 'stereo_fuzzy_perception.nodes.stereo_camera_parameters',
    'gantry_driver_node': 'cartesian_3p_driver.gantry_driver_parameters',
    'fake_gantry': 'cartesian_3p_driver.fake_gantry_parameters',
}
# Every README that holds parameter blocks (the top-level one holds all nodes).
READMES = (REPO_ROOT / 'README.md', REPO_ROOT / 'src/stereo_fuzzy_perception/README.md',
           REPO_ROOT / 'src/cartesian_3p_driver/README.md')
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
