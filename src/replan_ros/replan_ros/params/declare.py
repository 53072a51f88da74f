"""A node's parameters in rclpy: ``declare_node_parameters`` checks the node's own parameter
files and ``-p`` values against its table (a problem is one ``config error:`` line and exit code
2), declares every parameter with a descriptor carrying its description, unit, range and
``read_only`` (the nodes read their parameters once at start), and refuses run-time changes
that are read-only or invalid; rclpy's message types are imported on call, so importing
``replan_ros.params`` does not need them.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from typing import Any

from replan_ros.params.files import resolve, sources_from_argv
from replan_ros.params.spec import INF, RESTART_HINT, ConfigError, _fmt, check_value
from replan_ros.params.tables import table


def declare_node_parameters(node, table_name: str | None = None,
                            on_change: Callable[[str, Any], None] | None = None,
                            argv: Sequence[str] | None = None) -> dict[str, Any]:
    """Check the node's own parameter files and -p values against its table (a problem is
    logged as one ``config error:`` line and the process exits with code 2), declare every
    parameter with its descriptor (range, read-only, description with unit), and refuse
    run-time changes that are read-only or invalid. ``on_change(name, value)`` applies an
    accepted change of a writable parameter. Returns {name: value}."""
    from rcl_interfaces.msg import (
        FloatingPointRange,
        IntegerRange,
        ParameterDescriptor,
        SetParametersResult,
    )

    name = table_name or node.get_name()
    try:
        sources = sources_from_argv(sys.argv if argv is None else argv, node.get_name())
        for source in sources:        # this process reads its own name's sections
            source.sections = {name if k == node.get_name() else k: v
                               for k, v in source.sections.items()
                               if k in (node.get_name(), '**')}
        values = resolve(sources, [name]).values[name]
    except ConfigError as err:
        node.get_logger().fatal(f'config error: {err}')
        raise SystemExit(2) from None
    specs = table(name)
    for spec in specs.values():
        descriptor = ParameterDescriptor(description=spec.full_description(),
                                         read_only=spec.read_only)
        constraints = []
        if spec.choices:
            constraints.append('one of ' + ', '.join(map(str, spec.choices)))
        if spec.length is not None:
            constraints.append(f'{spec.length} values')
        if spec.is_list and (spec.min is not None or spec.max is not None):
            constraints.append(f'each in {spec.range_text()}')
        descriptor.additional_constraints = '; '.join(constraints)
        if spec.kind == 'float' and (spec.min is not None or spec.max is not None):
            descriptor.floating_point_range = [FloatingPointRange(
                from_value=float(-INF if spec.min is None else spec.min),
                to_value=float(INF if spec.max is None else spec.max), step=0.0)]
        elif spec.kind == 'int' and (spec.min is not None or spec.max is not None):
            descriptor.integer_range = [IntegerRange(
                from_value=int(-2 ** 63 if spec.min is None else spec.min),
                to_value=int(2 ** 63 - 1 if spec.max is None else spec.max), step=1)]
        # The value was checked above from the same files; rclpy's own override would refuse
        # an int for a float, which ROS files commonly hold.
        node.declare_parameter(spec.name, values[spec.name], descriptor, ignore_override=True)

    def on_set(parameters) -> SetParametersResult:
        for parameter in parameters:
            spec = specs.get(parameter.name)
            if spec is None:
                continue              # rclpy's own (use_sim_time)
            if spec.read_only:
                return SetParametersResult(successful=False, reason=(
                    f'{name}.{spec.name} is read-only: {RESTART_HINT}'))
            try:
                check_value(spec, parameter.value)
            except ConfigError as err:
                return SetParametersResult(successful=False, reason=(
                    f'{name}.{spec.name} = {_fmt(parameter.value)} {err}'))
        return SetParametersResult(successful=True)

    def post_set(parameters) -> None:
        for parameter in parameters:
            if parameter.name in specs and on_change is not None:
                on_change(parameter.name, parameter.value)

    node.add_on_set_parameters_callback(on_set)
    node.add_post_set_parameters_callback(post_set)
    return dict(values)
