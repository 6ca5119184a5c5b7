"""The launch files and chain/processes.py start the same processes: those of the description.

`launch` and `launch_ros` are not installable here, so each launch file is run against small
stand-ins for the few launch classes it uses, which record what they are given. The nodes each
launch file would start are then compared with the command lines the repository's process
starter builds from src/stereo_fuzzy_perception/launch/chain_processes.yaml.
"""

from __future__ import annotations

import ast
import runpy
import sys
import types
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
LAUNCH_DIR = REPO_ROOT / 'src' / 'stereo_fuzzy_perception' / 'launch'
DESCRIPTION = LAUNCH_DIR / 'chain_processes.yaml'
LAUNCH_FILES = sorted(LAUNCH_DIR.glob('*.launch.py'))


class Recorded:
    """A stand-in for a launch class: keeps its positional and keyword arguments."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        self.args = args
        self.kwargs = kwargs


class FakeLaunchConfiguration:
    def __init__(self, name: str) -> None:
        self.name = name

    def perform(self, context: dict[str, str]) -> str:
        return context[self.name]


def _install_stand_ins(monkeypatch: pytest.MonkeyPatch) -> None:
    def module(name: str, **attributes: object) -> None:
        stand_in = types.ModuleType(name)
        for key, value in attributes.items():
            setattr(stand_in, key, value)
        monkeypatch.setitem(sys.modules, name, stand_in)

    classes = {name: type(name, (Recorded,), {}) for name in (
        'LaunchDescription', 'DeclareLaunchArgument', 'OpaqueFunction', 'Node')}
    module('launch', LaunchDescription=classes['LaunchDescription'])
    module('launch.actions', DeclareLaunchArgument=classes['DeclareLaunchArgument'],
           OpaqueFunction=classes['OpaqueFunction'])
    module('launch.substitutions', LaunchConfiguration=FakeLaunchConfiguration)
    module('launch_ros')
    module('launch_ros.actions', Node=classes['Node'])
    module('ament_index_python')
    module('ament_index_python.packages',
           get_package_share_directory=lambda package: str(REPO_ROOT / 'src' / package))


def launched_nodes(launch_file: Path, monkeypatch: pytest.MonkeyPatch,
                   given: dict[str, str]) -> tuple[dict[str, str], list[dict]]:
    """Run a launch file against the stand-ins; return its arguments' defaults and the keyword
    arguments of every Node it starts with `given` launch arguments."""
    _install_stand_ins(monkeypatch)
    description = runpy.run_path(str(launch_file))['generate_launch_description']()
    entities = description.args[0]
    defaults = {entity.args[0]: entity.kwargs['default_value'] for entity in entities
                if type(entity).__name__ == 'DeclareLaunchArgument'}
    opaque = [entity for entity in entities if type(entity).__name__ == 'OpaqueFunction']
    assert len(opaque) == 1, f'{launch_file.name}: expected one OpaqueFunction'
    nodes = opaque[0].kwargs['function'](dict(defaults, **given))
    return defaults, [node.kwargs for node in nodes]


def command_line_of(node: dict) -> list[str]:
    """Return the --ros-args that launch_ros would give a Node with these keyword arguments."""
    from stereo_fuzzy_perception.bringup.chain_description import format_parameter_value

    line = ['--ros-args', '-r', f'__node:={node["name"]}']
    if node.get('namespace'):  # launch_ros pushes a relative namespace under the root
        line += ['-r', f'__ns:=/{node["namespace"].lstrip("/")}']
    for entry in node['parameters']:
        if isinstance(entry, dict):
            line += [item for name, value in entry.items()
                     for item in ('-p', f'{name}:={format_parameter_value(value)}')]
        else:
            line += ['--params-file', entry]
    for source, target in node['remappings']:
        line += ['-r', f'{source}:={target}']
    return line


def test_every_set_has_a_launch_file_and_every_launch_file_a_set():
    from stereo_fuzzy_perception.bringup.chain_description import load_description

    sets = set(load_description(DESCRIPTION).sets)
    stems = {path.name.removesuffix('.launch.py') for path in LAUNCH_FILES}
    assert sets == stems, f'sets {sorted(sets)} but launch files {sorted(stems)}'
    for path in LAUNCH_FILES:
        assigned = [node.value.value for node in ast.walk(ast.parse(path.read_text()))
                    if isinstance(node, ast.Assign) and any(
                        isinstance(target, ast.Name) and target.id == 'PROCESS_SET'
                        for target in node.targets)]
        assert assigned == [path.name.removesuffix('.launch.py')], (
            f'{path.name} must start the set named after it, starts {assigned}')


def test_described_files_and_executables_exist():
    from stereo_fuzzy_perception.bringup.chain_description import load_description

    for process in load_description(DESCRIPTION).processes.values():
        setup = (REPO_ROOT / 'src' / process.package / 'setup.py').read_text()
        assert f"'{process.executable} = " in setup, (
            f'{process.package} installs no executable {process.executable}')
        for relative in process.parameter_files:
            assert (REPO_ROOT / 'src' / process.package / relative).is_file(), (
                f'{process.name}: {process.package}/{relative} does not exist')


@pytest.mark.parametrize('launch_file', LAUNCH_FILES, ids=[p.name for p in LAUNCH_FILES])
@pytest.mark.parametrize('given', [{}, {'params_file': 'chain/demo_params.yaml',
                                        'port': '/dev/ttyUSB3'}], ids=['defaults', 'given'])
def test_launch_file_starts_what_the_process_starter_starts(launch_file, given, monkeypatch):
    from stereo_fuzzy_perception.bringup.chain_description import ros_arguments

    from chain.processes import process_set, source_share_directory

    processes = process_set(launch_file.name.removesuffix('.launch.py'))
    defaults, nodes = launched_nodes(launch_file, monkeypatch, given)
    assert defaults == {a.name: a.default for a in processes.arguments}
    arguments = processes.argument_values(given)
    assert [(n['package'], n['executable'], n['name']) for n in nodes] == [
        (p.package, p.executable, p.name) for p in processes.processes]
    for node, process in zip(nodes, processes.processes, strict=True):
        assert command_line_of(node) == ros_arguments(process, arguments,
                                                      source_share_directory), process.name


def test_chain_without_hardware_links_the_driver_to_the_simulator(monkeypatch):
    _, nodes = launched_nodes(LAUNCH_DIR / 'chain_without_hardware.launch.py', monkeypatch,
                              {'port': '/tmp/gantry_link'})
    overrides = {node['name']: node['parameters'][-1] for node in nodes if node['parameters']}
    assert overrides['fake_gantry'] == {'link_path': '/tmp/gantry_link'}
    assert overrides['gantry_driver_node'] == {'port': '/tmp/gantry_link'}


def test_ros_arguments_lay_out_files_overrides_and_remappings_in_order(tmp_path):
    import yaml
    from stereo_fuzzy_perception.bringup.chain_description import ProcessSpec, ros_arguments

    (tmp_path / 'pkg' / 'config').mkdir(parents=True)
    own = tmp_path / 'pkg' / 'config' / 'a.yaml'
    own.write_text('corr:\n  ros__parameters: {rate: 1.0}\n')
    given = tmp_path / 'p.yaml'
    given.write_text('/**:\n  ros__parameters: {x: 1}\n')  # already any namespace: kept
    process = ProcessSpec('corr', 'pkg', 'correlation_node', ('config/a.yaml',),
                          (('port', '$(port)'), ('rate', 2.5), ('on', True)),
                          (('pair', '/rig1/pair'), ('matches', '$(namespace)/matches')),
                          namespace='$(namespace)')
    line = ros_arguments(process, {'port': '/dev/x', 'params_file': str(given),
                                   'namespace': 'stereo'}, lambda package: tmp_path / package)
    rewritten = Path(line[line.index('--params-file') + 1])
    assert line == ['--ros-args', '-r', '__node:=corr', '-r', '__ns:=/stereo', '--params-file',
                    str(rewritten), '--params-file', str(given), '-p', 'port:=/dev/x',
                    '-p', 'rate:=2.5', '-p', 'on:=true', '-r', 'pair:=/rig1/pair',
                    '-r', 'matches:=stereo/matches']
    assert yaml.safe_load(rewritten.read_text()) == {
        '/**/corr': {'ros__parameters': {'rate': 1.0}}}, 'a namespaced node reads corr:'
    at_root = ros_arguments(process, {'port': '/dev/x', 'namespace': '/'},
                            lambda package: tmp_path / package)
    assert '__ns:=/' not in ' '.join(at_root) and 'matches:=/matches' in at_root, at_root
    assert str(own) in at_root, 'a node at the root reads its files as they are'


def test_default_chain_has_its_top_level_topics_and_no_doubled_prefix():
    """With the default arguments the product's topics are /stereo/pair, /stereo/matches and
    /best_point; with namespace:=/stereo the same, never /stereo/stereo/..."""
    from stereo_fuzzy_perception.nodes import topic_names

    from chain.processes import process_set

    processes = {process.name: process for process in process_set('camera_rig').processes}
    for given in ({}, {'namespace': '/stereo'}, {'namespace': 'stereo'}):
        arguments = process_set('camera_rig').argument_values(given)
        namespace = {name: process.resolved_namespace(arguments)
                     for name, process in processes.items()}
        remaps = dict(processes['fuzzy_best_point_node'].resolved_remappings(arguments))
        pair = topic_names.in_namespace(namespace['stereo_sync_node'], topic_names.PAIR)
        matches = topic_names.in_namespace(namespace['correlation_node'], topic_names.MATCHES)
        assert (pair, matches) == ('/stereo/pair', '/stereo/matches'), given
        assert topic_names.in_namespace(namespace['fuzzy_best_point_node'],
                                        remaps[topic_names.MATCHES]) == matches, given
        assert topic_names.in_namespace(namespace['fuzzy_best_point_node'],
                                        topic_names.BEST_POINT) == '/best_point', given


@pytest.mark.parametrize(('text', 'message'), [
    ('processes: {a: {package: p}}', 'processes.a.executable'),
    ('processes: {a: {package: p, executable: e, colour: red}}', 'unknown key(s) colour'),
    ('processes: {}\nsets: {s: {processes: [b]}}', 'unknown process(es) b'),
    ('processes: {}\nsets: {s: {processes: [], arguments: {port: x}}}', 'unknown argument(s)'),
    ('processes: [1, 2]', 'must be a mapping'),
])
def test_malformed_description_is_refused_with_the_entry_named(tmp_path, text, message):
    from stereo_fuzzy_perception.bringup.chain_description import (
        ChainDescriptionError,
        load_description,
    )

    path = tmp_path / 'chain.yaml'
    path.write_text(text)
    with pytest.raises(ChainDescriptionError, match=message.replace('(', r'\(').replace(
            ')', r'\)')):
        load_description(path)


def test_unknown_set_and_argument_are_refused():
    from stereo_fuzzy_perception.bringup.chain_description import (
        ChainDescriptionError,
        load_description,
    )

    description = load_description(DESCRIPTION)
    with pytest.raises(ChainDescriptionError, match='no set'):
        description.process_set('everything')
    with pytest.raises(ChainDescriptionError, match='no argument'):
        description.process_set('chain').argument_values({'prot': '/dev/ttyUSB0'})


def test_every_node_gets_the_packages_dds_profile_unless_the_user_has_one(monkeypatch):
    from stereo_fuzzy_perception.bringup.chain_description import (
        DDS_PROFILES_FILE,
        DDS_PROFILES_VARIABLE,
    )

    profile = REPO_ROOT / 'src' / 'stereo_fuzzy_perception' / 'config' / DDS_PROFILES_FILE
    assert profile.is_file()
    for launch_file in LAUNCH_FILES:
        monkeypatch.delenv(DDS_PROFILES_VARIABLE, raising=False)
        _, nodes = launched_nodes(launch_file, monkeypatch, {})
        assert nodes and all(node['additional_env'] == {DDS_PROFILES_VARIABLE: str(profile)}
                             for node in nodes), launch_file.name
        monkeypatch.setenv(DDS_PROFILES_VARIABLE, '/my/own/profile.xml')
        _, nodes = launched_nodes(launch_file, monkeypatch, {})
        assert all(node['additional_env'] == {} for node in nodes), launch_file.name
