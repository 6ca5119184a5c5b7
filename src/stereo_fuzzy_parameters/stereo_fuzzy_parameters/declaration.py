"""Declare ParameterSpec lists on an rclpy node, with descriptors that rclpy enforces."""

from __future__ import annotations

from collections.abc import Callable, Sequence

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.node import Node
from rclpy.parameter import Parameter

from stereo_fuzzy_parameters.spec import ParameterSpec, ParameterValue


def _descriptor(spec: ParameterSpec) -> ParameterDescriptor:
    descriptor = ParameterDescriptor(
        description=spec.description,
        additional_constraints=spec.constraint_text(),
        read_only=spec.read_only,
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


def declare_parameters(
    node: Node,
    specs: Sequence[ParameterSpec],
    validate: Callable[[dict[str, ParameterValue]], str | None] | None = None,
    apply: Callable[[dict[str, ParameterValue]], None] | None = None,
) -> dict[str, ParameterValue]:
    """Declare `specs` on `node` and return their current values by name.

    Ranges are enforced by rclpy at declare time and on every set; choices and the optional
    `validate` hook (which sees all values after the change) are checked in an on-set
    callback, which rejects the whole change with the reason. `apply` runs after a change
    was accepted, with the new values.

    Args:
        node: The node to declare on.
        specs: The node's parameter specs.
        validate: Cross-parameter check returning a reason to reject, or None.
        apply: Called with all values after an accepted change.

    Returns:
        The declared values, by parameter name.
    """
    by_name = {spec.name: spec for spec in specs}
    for spec in specs:
        node.declare_parameter(spec.name, spec.default, _descriptor(spec))
    values: dict[str, ParameterValue] = {
        spec.name: node.get_parameter(spec.name).value for spec in specs
    }
    for spec in specs:
        reason = spec.check(values[spec.name])
        if reason:
            raise ValueError(reason)
    if validate is not None:
        reason = validate(values)
        if reason:
            raise ValueError(reason)

    def on_set(parameters: list[Parameter]) -> SetParametersResult:
        proposed = dict(values)
        for parameter in parameters:
            spec = by_name.get(parameter.name)
            if spec is None:
                continue
            reason = spec.check(parameter.value)
            if reason:
                return SetParametersResult(successful=False, reason=reason)
            proposed[parameter.name] = parameter.value
        if validate is not None:
            reason = validate(proposed)
            if reason:
                return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def after_set(parameters: list[Parameter]) -> None:
        for parameter in parameters:
            if parameter.name in by_name:
                values[parameter.name] = parameter.value
        if apply is not None:
            apply(dict(values))

    node.add_on_set_parameters_callback(on_set)
    node.add_post_set_parameters_callback(after_set)
    return values
