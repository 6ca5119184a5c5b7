"""Declare a node's settings type on an rclpy node, and run a node that may fail to start.

`declare_settings` declares every parameter of a settings type (spec.py) with descriptors
that rclpy enforces, checks the values, and returns the typed settings object; an on-set
callback builds the proposed settings object and validates it, and the node's `apply` receives
the new settings once a change is accepted. `run_node` is every node's main: a StartupError
(bad parameter, missing file, unusable device) ends the node with one FATAL line and exit
code 1, no traceback.
"""

from __future__ import annotations

import difflib
import sys
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

import rclpy
from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.executors import ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter

from stereo_fuzzy_parameters.spec import (
    ParameterSpec,
    ParameterValue,
    SettingsError,
    parameter_specs,
    settings_from_values,
)

S = TypeVar('S')
N = TypeVar('N', bound=Node)


class StartupError(ValueError):
    """The node cannot start; the message is one line naming what, its value and what is allowed.

    Args:
        message: The line to log, e.g. `window_size=10 must be odd`.
        node_name: The node's name, for the logger of the FATAL line.
    """

    def __init__(self, message: str, node_name: str = '') -> None:
        super().__init__(' '.join(message.split()))
        self.node_name = node_name


def _descriptor(spec: ParameterSpec) -> ParameterDescriptor:
    descriptor = ParameterDescriptor(
        description=spec.description,
        additional_constraints=spec.constraint_text(),
        read_only=spec.read_only,
        dynamic_typing=spec.dynamic_typing,
    )
    is_number = isinstance(spec.default, (int, float)) and not isinstance(spec.default, bool)
    if is_number and (spec.minimum is not None or spec.maximum is not None):
        low = spec.minimum if spec.minimum is not None else -1e300
        high = spec.maximum if spec.maximum is not None else 1e300
        if isinstance(spec.default, int):
            descriptor.integer_range = [
                IntegerRange(from_value=int(max(low, -2**62)), to_value=int(min(high, 2**62)))
            ]
        else:
            descriptor.floating_point_range = [
                FloatingPointRange(from_value=float(low), to_value=float(high))
            ]
    return descriptor


def _type_words(default: ParameterValue) -> str:
    if isinstance(default, bool):
        return 'true or false'
    if isinstance(default, int):
        return 'an integer'
    if isinstance(default, float):
        return 'a floating-point number such as 1.0, not 1'
    if isinstance(default, list):
        element = default[0] if default else ''
        kind = ('floating-point numbers such as 1.0, not 1' if isinstance(element, float)
                else 'integers' if isinstance(element, int) else 'strings')
        return f'a list of {kind}'
    return 'a string'


def _overrides(node: Node) -> dict[str, Any]:
    """Return the parameters given on the command line or in a params file, by name."""
    # rclpy keeps them only in this attribute; its exceptions do not carry the value.
    return dict(getattr(node, '_parameter_overrides', {}))


def _given_value(node: Node, name: str) -> Any:
    """Return the value given for `name` on the command line or in a params file."""
    override = _overrides(node).get(name)
    return None if override is None else override.value


def _warn_unknown(node: Node, names: Sequence[str]) -> None:
    """Warn once per given parameter the node does not have (rclpy ignores it silently)."""
    for name in sorted(_overrides(node)):
        if node.has_parameter(name):
            continue
        close = difflib.get_close_matches(name, names, n=1)
        hint = f'; did you mean {close[0]}?' if close else ''
        node.get_logger().warning(f'parameter {name} is not a parameter of {node.get_name()} '
                                  f'and is ignored{hint}')


def _declare(node: Node, spec: ParameterSpec) -> None:
    """Declare one parameter; a value rclpy refuses becomes a one-line StartupError."""
    try:
        node.declare_parameter(spec.name, spec.default, _descriptor(spec))
    except InvalidParameterTypeException:
        given = _given_value(node, spec.name)
        constraint = spec.constraint_text()
        allowed = f'; allowed {constraint}' if constraint else ''
        raise StartupError(f'{spec.name}={given!r} is not allowed: expected '
                           f'{_type_words(spec.default)}{allowed}', node.get_name()) from None
    except InvalidParameterValueException as error:
        given = _given_value(node, spec.name)
        reason = spec.check(given) or f'{spec.name}={given!r} is not allowed ({error})'
        raise StartupError(reason, node.get_name()) from None


def declare_settings(
    node: Node,
    settings_type: type[S],
    apply: Callable[[S], None] | None = None,
    check: Callable[[S], str | None] | None = None,
) -> S:
    """Declare the parameters of `settings_type` on `node` and return the settings object.

    rclpy enforces types and ranges at declare time and on every set; array sizes, choices,
    the settings type's `problem()` methods and `check` are validated on the proposed settings
    object in an on-set callback, which refuses the whole change with the reason. `apply`
    then receives the new settings object.

    Args:
        node: The node to declare on.
        settings_type: The node's settings type (a frozen dataclass of `parameter()` fields).
        apply: Called with the new settings after an accepted change.
        check: A further check needing more than the values (e.g. that a file loads),
            returning a reason to refuse, or None.

    Returns:
        The settings at start-up.

    Raises:
        StartupError: A value or combination of values the node cannot start with.
    """
    specs = parameter_specs(settings_type)
    names = {spec.name for spec in specs}
    for spec in specs:
        _declare(node, spec)
    values: dict[str, object] = {spec.name: node.get_parameter(spec.name).value
                                 for spec in specs}

    def validated(candidate: dict[str, object]) -> S:
        settings = settings_from_values(settings_type, candidate)
        reason = check(settings) if check is not None else None
        if reason:
            raise SettingsError(reason)
        return settings

    try:
        settings = validated(values)
    except SettingsError as error:
        raise StartupError(str(error), node.get_name()) from None
    _warn_unknown(node, [spec.name for spec in specs])

    def on_set(parameters: list[Parameter]) -> SetParametersResult:
        ours = [parameter for parameter in parameters if parameter.name in names]
        if not ours:
            return SetParametersResult(successful=True)
        proposed = dict(values)
        proposed.update({parameter.name: parameter.value for parameter in ours})
        try:
            validated(proposed)
        except SettingsError as error:
            return SetParametersResult(successful=False, reason=str(error))
        except Exception as error:  # a check must not take the parameter service down
            return SetParametersResult(successful=False, reason=f'{type(error).__name__}: '
                                                                f'{error}')
        return SetParametersResult(successful=True)

    def after_set(parameters: list[Parameter]) -> None:
        ours = [parameter for parameter in parameters if parameter.name in names]
        if not ours:
            return
        values.update({parameter.name: parameter.value for parameter in ours})
        if apply is None:
            return
        try:
            apply(settings_from_values(settings_type, values))
        except Exception as error:  # validated already; if applying still fails, say so, go on
            node.get_logger().error(f'new parameter values not applied: {error!r}')

    node.add_on_set_parameters_callback(on_set)
    node.add_post_set_parameters_callback(after_set)
    return settings


def run_node(node_type: Callable[[], N], args: list[str] | None = None) -> None:
    """Run a node until shutdown: every node's `main`.

    A StartupError raised while the node is built is logged as one FATAL line and the process
    exits with code 1; Ctrl-C and an external shutdown end it normally, also when rclpy's
    signal handler shuts the context down while spin is building its wait set (spin then
    raises RCLError, "the given context is not valid": ros2/rclpy#1166).

    Args:
        node_type: Builds the node (its class).
        args: Command-line arguments for rclpy.init (None: sys.argv).
    """
    rclpy.init(args=args)
    node: N | None = None
    failed = False
    try:
        node = node_type()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except _rclpy.RCLError:
        if rclpy.ok():  # not the shutdown race: a real failure
            raise
    except StartupError as error:
        logger_name = error.node_name or getattr(node_type, '__name__', 'node')
        rclpy.logging.get_logger(logger_name).fatal(f'cannot start: {error}')
        failed = True
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    if failed:
        sys.exit(1)

