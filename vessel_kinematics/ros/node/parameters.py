"""
The node's parameters: :data:`~vessel_kinematics.ros.params.PARAMETERS` declared, checked, applied.

:class:`NodeParameters` declares every parameter of the table, typed, with its description,
range and choices, and with ``read_only`` for the structural ones (frames, ``projection``,
``motion``: set at start-up only). ``use_sim_time`` is made read-only too: a peer that switched
the node to a ``/clock`` nobody publishes would stop its diagnostics clock. A ``ros2 param set``
is validated against the other current values (:meth:`~vessel_kinematics.ros.params.
NavigatorParams.from_flat`) and against the node's state (``check(old, new)``: an origin far
from the vessel, a ``max_gap`` shorter than the inputs' periods), and refused with its one-line
reason; once set, the new parameters
go to the ``apply`` callback.
"""

from __future__ import annotations

import array
from typing import Any, Callable

from rcl_interfaces.msg import (FloatingPointRange, ParameterDescriptor, ParameterType,
                                SetParametersResult)
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.node import Node
from rclpy.parameter import Parameter as RosParameter
from vessel_kinematics.ros.params import NavigatorParams, Parameter, ParameterError, PARAMETERS

__all__ = ['NodeParameters', 'StartupError']


class StartupError(RuntimeError):
    """The node cannot start: a parameter is invalid. The message says which and why."""


def _descriptor_type(default: Any) -> int:
    """Return the rcl_interfaces ParameterType of a parameter from its default value."""
    if isinstance(default, bool):
        return ParameterType.PARAMETER_BOOL
    if isinstance(default, str):
        return ParameterType.PARAMETER_STRING
    if isinstance(default, int):
        return ParameterType.PARAMETER_INTEGER
    if isinstance(default, float):
        return ParameterType.PARAMETER_DOUBLE
    if isinstance(default, list) and default and isinstance(default[0], str):
        return ParameterType.PARAMETER_STRING_ARRAY
    if isinstance(default, list):
        return ParameterType.PARAMETER_DOUBLE_ARRAY
    raise TypeError(f'no ROS parameter type for the default {default!r}')


def _plain(value: Any) -> Any:
    """Return a ROS parameter value as from_flat expects it (arrays become lists)."""
    if isinstance(value, (array.array, tuple)):
        return list(value)
    return value


def _descriptor(parameter: Parameter, kind: int) -> ParameterDescriptor:
    numeric = kind in (ParameterType.PARAMETER_DOUBLE, ParameterType.PARAMETER_DOUBLE_ARRAY)
    # Doubles take integers too (users write max_gap: 2, origin: [59, 10, 0]): typed
    # dynamically, then checked by from_flat and stored as doubles.
    descriptor = ParameterDescriptor(
        name=parameter.name, type=kind, description=parameter.description,
        dynamic_typing=numeric, read_only=parameter.read_only)
    if parameter.choices is not None:
        descriptor.additional_constraints = 'one of ' + ', '.join(parameter.choices)
    if (kind == ParameterType.PARAMETER_DOUBLE and parameter.low is not None
            and parameter.high is not None):
        descriptor.floating_point_range = [FloatingPointRange(
            from_value=float(parameter.low), to_value=float(parameter.high))]
    return descriptor


class NodeParameters:
    """The navigator's parameters on ``node``; ``apply(params, changed names)`` gets changes."""

    def __init__(self, node: Node, apply: Callable[[NavigatorParams, list[str]], None],
                 check: Callable[[NavigatorParams, NavigatorParams], str | None] | None = None
                 ) -> None:
        self._node = node
        self._apply = apply
        self._check = check
        self._pending: NavigatorParams | None = None
        numeric = []
        for parameter in PARAMETERS:
            kind = _descriptor_type(parameter.default)
            try:
                node.declare_parameter(parameter.name, parameter.default,
                                       _descriptor(parameter, kind))
            except (InvalidParameterTypeException, InvalidParameterValueException) as error:
                expected = RosParameter.Type(kind).name.lower().replace('_', ' ')
                raise StartupError(
                    f'parameter {parameter.name!r}: must be a {expected} '
                    f'(e.g. {parameter.default!r}); {error}') from error
            if kind in (ParameterType.PARAMETER_DOUBLE, ParameterType.PARAMETER_DOUBLE_ARRAY):
                numeric.append((parameter.name, kind))
        self._store_as_doubles(numeric)
        use_sim_time = node.get_parameter('use_sim_time').value
        node.set_descriptor('use_sim_time', ParameterDescriptor(
            type=ParameterType.PARAMETER_BOOL, read_only=True,
            description='use /clock (set at start-up only)'))
        self.use_sim_time = bool(use_sim_time)
        try:
            self.params = NavigatorParams.from_flat(self._values())
        except ParameterError as error:
            raise StartupError(str(error)) from error
        node.add_on_set_parameters_callback(self._on_set)
        node.add_post_set_parameters_callback(self._after_set)

    def _store_as_doubles(self, names: list[tuple[str, int]]) -> None:
        """Store integer values of double parameters as doubles (refuse non-numbers)."""
        coerced = []
        for name, kind in names:
            value = _plain(self._node.get_parameter(name).value)
            if kind == ParameterType.PARAMETER_DOUBLE:
                if isinstance(value, bool) or not isinstance(value, (int, float)):
                    raise StartupError(f'parameter {name!r}: must be a double, got {value!r}')
                if isinstance(value, int):
                    coerced.append(RosParameter(name, RosParameter.Type.DOUBLE, float(value)))
                continue
            if not isinstance(value, list) or not all(
                    isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
                raise StartupError(f'parameter {name!r}: must be a list of doubles, got '
                                   f'{value!r}'[:200])
            if any(isinstance(v, int) for v in value):
                coerced.append(RosParameter(name, RosParameter.Type.DOUBLE_ARRAY,
                                            [float(v) for v in value]))
        if coerced:
            self._node.set_parameters(coerced)

    def _values(self) -> dict[str, Any]:
        """Return the navigator's parameter values by ROS name."""
        return {p.name: _plain(self._node.get_parameter(p.name).value) for p in PARAMETERS}

    def _on_set(self, parameters: list[RosParameter]) -> SetParametersResult:
        """Validate a change against the other current values; refuse with the reason."""
        values = self._values()
        for parameter in parameters:
            if parameter.name in values:
                values[parameter.name] = _plain(parameter.value)
        try:
            self._pending = NavigatorParams.from_flat(values)
        except ParameterError as error:
            self._pending = None
            return SetParametersResult(successful=False, reason=str(error))
        problem = self._check(self.params, self._pending) if self._check is not None else None
        if problem is not None:
            self._pending = None
            return SetParametersResult(successful=False, reason=problem)
        return SetParametersResult(successful=True)

    def _after_set(self, parameters: list[RosParameter]) -> None:
        """Hand the parameters once set to ``apply`` (when they changed anything)."""
        new, self._pending = self._pending, None
        if new is None or new == self.params:
            return
        old, self.params = self.params, new
        before = old.to_flat()
        self._apply(new, sorted(k for k, v in new.to_flat().items() if before[k] != v))
