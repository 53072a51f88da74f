"""Parameter files and the check of a run: YAML read the way rcl reads it (``load_yaml``,
``load_param_file``, ``parse_param_doc``: nested names flattened, ``/**`` kept as ``**``), the
sources of a run merged in order onto the table defaults with every key checked (``resolve``:
unknown node or key with the closest name, type, range, choices), the rules between parameters
of one node and between nodes (``cross_node_checks``), the launcher's whole check
(``check_run``) and a node's own sources from its command line (``sources_from_argv``); a
problem is one ``ConfigError`` line naming the file, node, key, value and what is allowed, e.g.
``/tmp/x.yaml: gait.replan_window = 0 is out of range [1, 8]``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from replan_core.common.types import LEGS
from replan_ros.params.spec import BUILTIN, ConfigError, _fmt, _suggest, check_value
from replan_ros.params.tables import TABLES, defaults, table


def _flatten(values: Mapping, prefix: str = '') -> dict[str, Any]:
    """``{estimator: {a: 1}}`` -> ``{'estimator.a': 1}`` (how rcl reads nested parameters)."""
    out = {}
    for key, value in values.items():
        name = f'{prefix}{key}'
        if isinstance(value, dict):
            out.update(_flatten(value, name + '.'))
        else:
            out[name] = value
    return out


def _section_node(section: str) -> str:
    return section.strip('/').split('/')[-1] if section not in ('/**', '**') else '**'


def parse_param_doc(doc: Any, label: str) -> dict[str, dict[str, Any]]:
    """A ROS parameter document -> {node: {name: value}} (nested names flattened, ``/**`` kept
    as ``**``); ConfigError for a malformed one."""
    if doc is None:
        return {}
    if not isinstance(doc, dict):
        raise ConfigError(f'{label}: the top level must map node names to sections')
    out: dict[str, dict[str, Any]] = {}
    for section, body in doc.items():
        if not isinstance(body, dict) or set(body) != {'ros__parameters'}:
            raise ConfigError(f'{label}: {section}: expected exactly one key ros__parameters '
                              f'under the node name')
        values = body['ros__parameters'] or {}
        if not isinstance(values, dict):
            raise ConfigError(f'{label}: {section}.ros__parameters must be a mapping')
        out.setdefault(_section_node(str(section)), {}).update(_flatten(values))
    return out


class _RosLoader(yaml.SafeLoader):
    """YAML as rcl reads parameter files: ``1.0e5`` is a float (YAML 1.1 wants ``1.0e+5``)."""


_RosLoader.add_implicit_resolver(
    'tag:yaml.org,2002:float',
    re.compile(r'''^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
                |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
                |[-+]?\.(?:inf|Inf|INF)
                |\.(?:nan|NaN|NAN))$''', re.X),
    list('-+0123456789.'))


def load_yaml(text: str) -> Any:
    """A YAML document read the way rcl reads parameter files."""
    return yaml.load(text, Loader=_RosLoader)           # a SafeLoader subclass


def load_param_file(path: str | Path) -> dict[str, dict[str, Any]]:
    try:
        doc = load_yaml(Path(path).read_text())
    except OSError as err:
        raise ConfigError(f'{path}: cannot read: {err.strerror}') from err
    except yaml.YAMLError as err:
        line = str(err).replace('\n', ' ')
        raise ConfigError(f'{path}: not valid YAML: {line}') from err
    return parse_param_doc(doc, str(path))


@dataclass
class Source:
    """One parameter source of a run: a file (or a label) and its {node: {name: value}}."""

    label: str
    sections: dict[str, dict[str, Any]]
    nodes: tuple[str, ...] | None = None      # only these nodes read it (None: every node)


@dataclass
class Resolved:
    """Effective values per node, and where each came from ('default' or a source label)."""

    values: dict[str, dict[str, Any]] = field(default_factory=dict)
    origin: dict[str, dict[str, str]] = field(default_factory=dict)

    def where(self, node: str, name: str) -> str:
        return self.origin[node].get(name, 'default')


def resolve(sources: Sequence[Source], nodes: Iterable[str]) -> Resolved:
    """Check every key of every source against the tables (unknown node or key, type, range,
    choices) and merge them in order onto the defaults; ConfigError on the first problem."""
    nodes = list(nodes)
    result = Resolved()
    for node in nodes:
        result.values[node] = defaults(node)
        result.origin[node] = {}
    for source in sources:
        for section, values in source.sections.items():
            targets = nodes if section == '**' else [section]
            if section != '**' and section not in TABLES:
                raise ConfigError(f'{source.label}: {section} is not a node of the graph'
                                  f'{_suggest(section, TABLES)}; nodes: {", ".join(TABLES)}')
            for node in targets:
                if node not in result.values:
                    continue           # a node this run does not start (the recorder)
                if source.nodes is not None and node not in source.nodes:
                    continue
                specs = table(node)
                for name, value in values.items():
                    where = f'{source.label}: {node}.{name} = {_fmt(value)}'
                    if name in BUILTIN:
                        if not isinstance(value, BUILTIN[name]):
                            raise ConfigError(f'{where} has the wrong type: expected a bool')
                        continue
                    spec = specs.get(name)
                    if spec is None:
                        if section == '**':
                            continue   # a wildcard section may hold other nodes' keys
                        raise ConfigError(f'{where} is not a parameter of {node}'
                                          f'{_suggest(name, specs)}')
                    try:
                        result.values[node][name] = check_value(spec, value)
                    except ConfigError as err:
                        raise ConfigError(f'{where} {err}') from None
                    result.origin[node][name] = source.label
    for node in nodes:
        _node_checks(node, result)
    return result


def _value_at(resolved: Resolved, node: str, name: str) -> str:
    return (f'{node}.{name} = {_fmt(resolved.values[node][name])} '
            f'({resolved.where(node, name)})')


def _node_checks(node: str, r: Resolved) -> None:
    """Constraints between parameters of one node (also checked by the node itself)."""
    v = r.values[node]
    if node == 'gait' and sorted(v['sequence']) != sorted(LEGS):
        raise ConfigError(f'{r.where(node, "sequence")}: gait.sequence = {_fmt(v["sequence"])} '
                          f'must hold each leg of {", ".join(LEGS)} once')
    if node == 'mpc' and v['horizon'] < v['dt']:
        raise ConfigError(f'{_value_at(r, node, "horizon")} must be at least '
                          f'{_value_at(r, node, "dt")}')
    if node == 'mpc' and v['position_sway'] > 0.0 and v['position_weight'] == 0.0:
        raise ConfigError(f'{_value_at(r, node, "position_sway")} has no effect with '
                          f'{_value_at(r, node, "position_weight")}: the position term is off')
    if node == 'wbc' and v['fz_min'] >= v['fz_max']:
        raise ConfigError(f'{_value_at(r, node, "fz_min")} must be below '
                          f'{_value_at(r, node, "fz_max")}')
    if node == 'sim' and v['control_period'] < v['physics_dt']:
        raise ConfigError(f'{_value_at(r, node, "control_period")} must be at least '
                          f'{_value_at(r, node, "physics_dt")}')


def cross_node_checks(r: Resolved) -> None:
    """Values that two nodes hold and that must agree (checked by the launcher)."""
    if 'sim' in r.values and 'wbc' in r.values:
        period, rate = r.values['sim']['control_period'], r.values['wbc']['control_rate']
        if not math.isclose(rate * period, 1.0, rel_tol=1e-6):
            raise ConfigError(f'{_value_at(r, "wbc", "control_rate")} disagrees with '
                              f'{_value_at(r, "sim", "control_period")}: control_rate must be '
                              f'1 / control_period = {1.0 / period:g}')
        sim_pose = r.values['sim']['standing_joint_positions']
        wbc_pose = r.values['wbc']['standing_joint_positions']
        if any(abs(a - b) > 1e-9 for a, b in zip(sim_pose, wbc_pose, strict=True)):
            raise ConfigError(f'{_value_at(r, "wbc", "standing_joint_positions")} disagrees with '
                              f'{_value_at(r, "sim", "standing_joint_positions")}: the robot '
                              'stands up to the pose it spawns in (set both, or once in /**)')
        timeout, plan = r.values['sim']['command_timeout'], r.values['wbc']['plan_timeout']
        if timeout <= plan:
            raise ConfigError(f'{_value_at(r, "sim", "command_timeout")} must exceed '
                              f'{_value_at(r, "wbc", "plan_timeout")}: a slow re-plan would '
                              'be taken for a dead controller')


def check_run(sources: Sequence[Source], nodes: Iterable[str]) -> Resolved:
    """The launcher's check of a whole run: every file, every node, then cross-node rules."""
    resolved = resolve(sources, nodes)
    cross_node_checks(resolved)
    return resolved


def sources_from_argv(argv: Sequence[str], node: str) -> list[Source]:
    """The parameter sources on a node's command line, in rcl's order of precedence: every
    ``--params-file`` in order, then every ``-p name:=value`` (they win)."""
    files: list[Source] = []
    overrides: dict[str, Any] = {}
    in_ros_args = False
    args = list(argv)
    i = 0
    while i < len(args):
        arg = args[i]
        if arg == '--ros-args':
            in_ros_args = True
        elif arg == '--':
            in_ros_args = False
        elif in_ros_args and arg == '--params-file' and i + 1 < len(args):
            i += 1
            files.append(Source(args[i], load_param_file(args[i])))
        elif in_ros_args and arg in ('-p', '--param') and i + 1 < len(args):
            i += 1
            key, sep, text = args[i].partition(':=')
            if not sep:
                raise ConfigError(f'command line: -p {args[i]}: expected name:=value')
            try:
                overrides[key] = load_yaml(text)
            except yaml.YAMLError:
                overrides[key] = text
        i += 1
    if overrides:
        files.append(Source('command line (-p)', {node: _flatten(overrides)}))
    return files
