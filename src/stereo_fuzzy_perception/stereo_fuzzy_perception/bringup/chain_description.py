"""The chain's processes from one declarative file (launch/chain_processes.yaml). ROS-free.

The launch files (`ros2 launch stereo_fuzzy_perception chain.launch.py`) and this repository's
process starter (chain/processes.py) both build their processes from this description, so they
cannot start different executables, parameters files or remappings.
"""

from __future__ import annotations

import hashlib
import os
import re
import tempfile
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

DESCRIPTION_FILE = 'chain_processes.yaml'
DDS_PROFILES_VARIABLE = 'FASTRTPS_DEFAULT_PROFILES_FILE'
DDS_PROFILES_FILE = 'fastdds_large_messages.xml'
"""The package's Fast DDS profile (config/): a shared-memory segment that holds the chain's
large messages. Given to every node the launch files start unless the variable is set (then
the user's own profile wins); scripts/env.sh does the same for every other way of starting."""
# "$(name)": the value of the argument called name.
_ARGUMENT = re.compile(r'\$\((?P<name>\w+)\)')
ParameterValue = str | int | float | bool | list[Any]


class ChainDescriptionError(ValueError):
    """A description file that is malformed, or a set, process or argument it lacks."""


@dataclass(frozen=True)
class Argument:
    """A value given when starting a set (a launch argument)."""

    name: str
    default: str
    description: str


@dataclass(frozen=True)
class ProcessSpec:
    """One executable of the chain and how it is started.

    Attributes:
        name: The node name (also the name of its section in parameters files).
        package: The package that installs the executable.
        executable: The executable (what `ros2 run <package> <executable>` starts).
        parameter_files: Parameters files relative to the package's share directory, in order.
        overrides: Single parameters set after the files; "$(arg)" stands for an argument.
        remappings: (from, to) topic remappings; "$(arg)" in `to` stands for an argument.
        namespace: The node's namespace ('' = the root); "$(arg)" stands for an argument.
    """

    name: str
    package: str
    executable: str
    parameter_files: tuple[str, ...] = ()
    overrides: tuple[tuple[str, ParameterValue], ...] = ()
    remappings: tuple[tuple[str, str], ...] = ()
    namespace: str = ''

    def resolved_namespace(self, arguments: Mapping[str, str]) -> str:
        """Return the namespace with every "$(arg)" replaced ('' = the root).

        Raises:
            ChainDescriptionError: When it names an argument not in `arguments`.
        """
        namespace = _ARGUMENT.sub(self._substitution('namespace', arguments), self.namespace)
        return _collapse_slashes(namespace).rstrip('/')

    def resolved_remappings(self, arguments: Mapping[str, str]) -> list[tuple[str, str]]:
        """Return the remappings with every "$(arg)" in a target replaced.

        Raises:
            ChainDescriptionError: When a target names an argument not in `arguments`.
        """
        return [(source, _collapse_slashes(
            _ARGUMENT.sub(self._substitution(f'remapping {source}', arguments), target)))
            for source, target in self.remappings]

    def resolved_overrides(self, arguments: Mapping[str, str]) -> dict[str, ParameterValue]:
        """Return the overrides with every "$(arg)" replaced by its value in `arguments`.

        Raises:
            ChainDescriptionError: When an override names an argument not in `arguments`.
        """
        resolved: dict[str, ParameterValue] = {}
        for name, value in self.overrides:
            if isinstance(value, str):
                value = _ARGUMENT.sub(self._substitution(name, arguments), value)
            resolved[name] = value
        return resolved

    def _substitution(self, override: str,
                      arguments: Mapping[str, str]) -> Callable[[re.Match[str]], str]:
        def value_of(match: re.Match[str]) -> str:
            argument = match['name']
            if argument not in arguments:
                raise ChainDescriptionError(
                    f'{self.name}: override {override} uses $({argument}), which is not an '
                    f'argument; arguments: {", ".join(sorted(arguments))}')
            return arguments[argument]
        return value_of


@dataclass(frozen=True)
class ProcessSet:
    """The processes one launch file starts, and its arguments with their defaults."""

    name: str
    description: str
    processes: tuple[ProcessSpec, ...]
    arguments: tuple[Argument, ...]

    def argument_values(self, given: Mapping[str, str] | None = None) -> dict[str, str]:
        """Return every argument's value: `given` where set, the default otherwise.

        Raises:
            ChainDescriptionError: For a given argument that the set does not have.
        """
        values = {argument.name: argument.default for argument in self.arguments}
        unknown = sorted(set(given or {}) - set(values))
        if unknown:
            raise ChainDescriptionError(
                f'{self.name} has no argument(s) {", ".join(unknown)}; it has '
                + ', '.join(sorted(values)))
        values.update(given or {})
        return values


def _collapse_slashes(name: str) -> str:
    """Return `name` with runs of '/' made one ('$(namespace)/pair' with namespace '/')."""
    return re.sub('/{2,}', '/', name)


def parameters_for_any_namespace(path: Path) -> Path:
    """Return a parameters file whose `<node>:` sections also apply to namespaced nodes.

    rcl matches a section `stereo_sync_node:` only to /stereo_sync_node, so a node pushed into a
    namespace would silently ignore it (nav2 rewrites its YAML for the same reason). The copy
    turns every such key into `/**/stereo_sync_node:`, which rcl matches in any namespace, the
    root included; keys that already start with '/' are kept. A file without such keys is
    returned unchanged; the copy lives in the temporary directory, named by content.

    Raises:
        ChainDescriptionError: When the file cannot be read or is not a YAML mapping.
    """
    try:
        text = path.read_text()
        document = yaml.safe_load(text)
    except (OSError, yaml.YAMLError) as error:
        raise ChainDescriptionError(f'{path}: cannot read the parameters file ({error})') \
            from error
    if not isinstance(document, dict):
        raise ChainDescriptionError(f'{path}: a parameters file must be a mapping of node names')
    if all(str(key).startswith('/') for key in document):
        return path
    rewritten = {key if str(key).startswith('/') else f'/**/{key}': value
                 for key, value in document.items()}
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    folder = Path(tempfile.gettempdir()) / 'stereo_fuzzy_parameters'
    folder.mkdir(exist_ok=True)
    copy = folder / f'{path.stem}-{digest}.yaml'
    if not copy.exists():
        partial = copy.with_suffix(f'.{id(rewritten)}.tmp')
        partial.write_text(f'# {path} for nodes in any namespace (chain_description.py)\n'
                           + yaml.safe_dump(rewritten, sort_keys=False))
        partial.replace(copy)
    return copy


def format_parameter_value(value: ParameterValue) -> str:
    """Return `value` as a `-p name:=value` command-line value (YAML, as rcl parses it)."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, list):
        return '[' + ', '.join(format_parameter_value(item) for item in value) + ']'
    return str(value)


def parameter_files(process: ProcessSpec, arguments: Mapping[str, str],
                    share_directory: Callable[[str], Path]) -> list[Path]:
    """Return the parameters files of `process` in order: its own, then `params_file`.

    For a namespaced process each file goes through parameters_for_any_namespace, so its
    `<node>:` sections still apply.
    """
    paths = [share_directory(process.package) / relative for relative in process.parameter_files]
    if arguments.get('params_file'):
        paths.append(Path(arguments['params_file']))
    if process.resolved_namespace(arguments):
        paths = [parameters_for_any_namespace(path) for path in paths]
    return paths


def ros_arguments(process: ProcessSpec, arguments: Mapping[str, str],
                  share_directory: Callable[[str], Path]) -> list[str]:
    """Return the `--ros-args ...` list that starts `process` as the launch files start it.

    Args:
        process: The process.
        arguments: Every argument's value (ProcessSet.argument_values()).
        share_directory: The share directory of a package (where its parameters files are).
    """
    result = ['--ros-args', '-r', f'__node:={process.name}']
    namespace = process.resolved_namespace(arguments)
    if namespace:
        result += ['-r', f'__ns:=/{namespace.lstrip("/")}']  # rcl wants it absolute
    for path in parameter_files(process, arguments, share_directory):
        result += ['--params-file', str(path)]
    for name, value in process.resolved_overrides(arguments).items():
        result += ['-p', f'{name}:={format_parameter_value(value)}']
    for source, target in process.resolved_remappings(arguments):
        result += ['-r', f'{source}:={target}']
    return result


def _mapping(value: object, where: str) -> dict[str, Any]:
    if value is None:
        return {}
    if not isinstance(value, dict) or not all(isinstance(key, str) for key in value):
        raise ChainDescriptionError(f'{where} must be a mapping with string keys, got {value!r}')
    return value


def _strings(value: object, where: str) -> tuple[str, ...]:
    if value is None:
        return ()
    if not isinstance(value, list) or not all(isinstance(item, str) for item in value):
        raise ChainDescriptionError(f'{where} must be a list of strings, got {value!r}')
    return tuple(value)


def _process(name: str, entry: object, where: str) -> ProcessSpec:
    fields = _mapping(entry, where)
    unknown = sorted(set(fields) - {'package', 'executable', 'parameters', 'overrides',
                                    'remappings', 'namespace'})
    if unknown:
        raise ChainDescriptionError(f'{where}: unknown key(s) {", ".join(unknown)}')
    for key in ('package', 'executable'):
        if not isinstance(fields.get(key), str) or not fields[key]:
            raise ChainDescriptionError(f'{where}.{key} must be a non-empty string')
    remappings = _mapping(fields.get('remappings'), f'{where}.remappings')
    if not all(isinstance(target, str) for target in remappings.values()):
        raise ChainDescriptionError(f'{where}.remappings must map topic names to topic names')
    namespace = fields.get('namespace', '')
    if not isinstance(namespace, str):
        raise ChainDescriptionError(f'{where}.namespace must be a string, got {namespace!r}')
    return ProcessSpec(
        name=name, package=fields['package'], executable=fields['executable'],
        parameter_files=_strings(fields.get('parameters'), f'{where}.parameters'),
        overrides=tuple(_mapping(fields.get('overrides'), f'{where}.overrides').items()),
        remappings=tuple(remappings.items()), namespace=namespace)


@dataclass(frozen=True)
class ChainDescription:
    """Every process and set of a description file."""

    path: Path
    processes: dict[str, ProcessSpec]
    arguments: dict[str, Argument]
    sets: dict[str, tuple[str, tuple[str, ...], dict[str, str]]]

    def process_set(self, name: str) -> ProcessSet:
        """Return the set called `name`.

        Raises:
            ChainDescriptionError: When there is no such set.
        """
        if name not in self.sets:
            raise ChainDescriptionError(f'{self.path} has no set {name!r}; sets: '
                                        + ', '.join(sorted(self.sets)))
        description, names, defaults = self.sets[name]
        arguments = tuple(
            Argument(argument.name, defaults.get(argument.name, argument.default),
                     argument.description) for argument in self.arguments.values())
        return ProcessSet(name, description, tuple(self.processes[n] for n in names), arguments)


def load_description(path: Path) -> ChainDescription:
    """Read a description file (the format of launch/chain_processes.yaml).

    Raises:
        ChainDescriptionError: When the file cannot be read or is malformed; the message
            names the file and the entry.
    """
    try:
        document = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as error:
        raise ChainDescriptionError(f'{path}: cannot read the chain description ({error})') \
            from error
    top = _mapping(document, str(path))
    processes = {name: _process(name, entry, f'{path}: processes.{name}')
                 for name, entry in _mapping(top.get('processes'), f'{path}: processes').items()}
    arguments = {}
    for name, entry in _mapping(top.get('arguments'), f'{path}: arguments').items():
        fields = _mapping(entry, f'{path}: arguments.{name}')
        arguments[name] = Argument(name, str(fields.get('default', '')),
                                   str(fields.get('description', '')))
    sets = {}
    for name, entry in _mapping(top.get('sets'), f'{path}: sets').items():
        fields = _mapping(entry, f'{path}: sets.{name}')
        members = _strings(fields.get('processes'), f'{path}: sets.{name}.processes')
        missing = [member for member in members if member not in processes]
        if missing:
            raise ChainDescriptionError(f'{path}: set {name} names unknown process(es) '
                                        + ', '.join(missing))
        defaults = {key: str(value) for key, value in
                    _mapping(fields.get('arguments'), f'{path}: sets.{name}.arguments').items()}
        unknown = sorted(set(defaults) - set(arguments))
        if unknown:
            raise ChainDescriptionError(f'{path}: set {name} sets unknown argument(s) '
                                        + ', '.join(unknown))
        sets[name] = (str(fields.get('description', '')), members, defaults)
    return ChainDescription(path, processes, arguments, sets)


def launch_description(set_name: str, description_file: Path) -> Any:
    """Return the launch.LaunchDescription of a set (what a launch file's
    generate_launch_description returns): one DeclareLaunchArgument per argument and, at launch
    time, one launch_ros Node per process with the same parameters files, overrides and
    remappings as ros_arguments() gives the process starter.
    """
    from ament_index_python.packages import get_package_share_directory
    from launch import LaunchDescription  # type: ignore[attr-defined,unused-ignore]
    from launch.actions import DeclareLaunchArgument, OpaqueFunction
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node

    process_set = load_description(description_file).process_set(set_name)
    profiles = Path(get_package_share_directory('stereo_fuzzy_perception')) / 'config' / (
        DDS_PROFILES_FILE)
    environment = ({} if os.environ.get(DDS_PROFILES_VARIABLE)
                   else {DDS_PROFILES_VARIABLE: str(profiles)})

    def nodes(context: Any) -> list[Any]:
        values = {argument.name: LaunchConfiguration(argument.name).perform(context)
                  for argument in process_set.arguments}
        started = []
        for process in process_set.processes:
            parameters: list[Any] = [str(path) for path in parameter_files(
                process, values, lambda package: Path(get_package_share_directory(package)))]
            overrides = process.resolved_overrides(values)
            if overrides:
                parameters.append(overrides)
            started.append(Node(package=process.package, executable=process.executable,
                                name=process.name,
                                namespace=process.resolved_namespace(values) or None,
                                parameters=parameters,
                                remappings=process.resolved_remappings(values),
                                additional_env=environment, output='screen'))
        return started

    return LaunchDescription([
        *(DeclareLaunchArgument(argument.name, default_value=argument.default,
                                description=argument.description)
          for argument in process_set.arguments),
        OpaqueFunction(function=nodes),
    ])
