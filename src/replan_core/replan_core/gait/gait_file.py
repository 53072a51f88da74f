"""Gaits as data: one YAML file per gait, ``config/gaits/<name>.yaml`` (docs/gait.md, "Gait files").

A gait file says which legs swing together and in what order (``groups``: the crawl one leg at a
time, a trot the diagonal pairs), the swing and all-feet-down durations, the step height, the
step and set-point limits and the steps per plan. Its times, lengths and speeds are the
reference robot's (``config/robots/scaling.yaml``, ``reference``: HyQ), in s, m, m/s and rad/s.
The launcher gives them to the gait node as a parameter layer (``node_parameters``) before the
profile and the robot's, so another robot's values
follow by the scaling rules of ``scaling.yaml``, as every other parameter's (docs/robot_files.md,
"Scaling rules"). ``crawl.yaml`` gives exactly ``GaitParams()``'s crawl.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import yaml

from replan_core.common.types import LEGS
from replan_core.gait.crawl import GaitParams

# The numeric keys of a gait file: the gait node's parameters of the same names, which
# scaling.yaml scales for a robot.
NUMERIC_KEYS = ('swing_duration', 'four_feet_duration', 'idle_after', 'idle_replan_period',
                'step_height', 'max_step_length_x', 'max_step_length_y', 'max_linear_x',
                'max_linear_y', 'max_angular_z')
REQUIRED_KEYS = ('name', 'groups', 'swing_duration', 'four_feet_duration')
OPTIONAL_KEYS = ('description', 'n_footholds', *(k for k in NUMERIC_KEYS
                                                   if k not in REQUIRED_KEYS))


class GaitFileError(ValueError):
    """A gait file that cannot be used: the message names the file and the key."""


@dataclass(frozen=True)
class GaitSpec:
    """One gait file, in the reference robot's units."""

    name: str
    groups: tuple[tuple[int, ...], ...]      # leg indices (LEGS) per step, in swing order
    values: Mapping[str, float]              # the NUMERIC_KEYS given in the file
    n_footholds: int | None = None           # steps (groups) per plan; None: the base's
    description: str = ''

    @property
    def sequence(self) -> tuple[int, ...]:
        """The legs in swing order (GaitParams.sequence)."""
        return tuple(leg for group in self.groups for leg in group)

    @property
    def group_size(self) -> int:
        """Legs per step (1: the crawl, 2: a trot's diagonal pair)."""
        return len(self.groups[0])

    def params(self, base: GaitParams | None = None) -> GaitParams:
        """``base`` (default ``GaitParams()``) with this gait's groups, times and limits, in
        the reference robot's units."""
        base = GaitParams() if base is None else base
        values = dict(self.values)
        groups = self.groups if self.group_size > 1 else ()
        params = replace(base, sequence=self.sequence, groups=groups, **values)
        if self.n_footholds is not None:
            params = replace(params, n_footholds=self.n_footholds)
        params.validate()
        return params

    def node_parameters(self) -> dict[str, Any]:
        """The gait as the gait node's parameters (reference robot's units): ``gait``,
        ``sequence``, ``group_size``, its times and limits."""
        gait: dict[str, Any] = {'gait': self.name,
                                'sequence': [LEGS[leg] for leg in self.sequence],
                                'group_size': self.group_size}
        gait.update(self.values)
        if self.n_footholds is not None:
            gait['n_footholds'] = self.n_footholds
        return gait


def gait_file_path(name: str, config_dir: str | Path) -> Path:
    """``config_dir/gaits/<name>.yaml``; GaitFileError naming the gaits there if absent."""
    path = Path(config_dir) / 'gaits' / f'{name}.yaml'
    if not path.is_file():
        raise GaitFileError(f'unknown gait {name!r}: no {path}; gaits: '
                            f'{", ".join(gait_names(config_dir)) or "none"}')
    return path


def gait_names(config_dir: str | Path) -> list[str]:
    """The gaits of ``config_dir/gaits``, sorted."""
    return sorted(p.stem for p in (Path(config_dir) / 'gaits').glob('*.yaml'))


def _legs(group, where: str) -> tuple[int, ...]:
    if not isinstance(group, list) or not group:
        raise GaitFileError(f'{where}: a group is a non-empty list of legs, got {group!r}')
    legs = []
    for leg in group:
        if leg not in LEGS:
            raise GaitFileError(f'{where}: unknown leg {leg!r}; legs: {", ".join(LEGS)}')
        legs.append(LEGS.index(leg))
    return tuple(legs)


def parse_gait(doc: Mapping, label: str) -> GaitSpec:
    """A gait file's document; ``label`` names it in errors."""
    if not isinstance(doc, Mapping):
        raise GaitFileError(f'{label}: not a mapping')
    missing = [k for k in REQUIRED_KEYS if k not in doc]
    unknown = [k for k in doc if k not in REQUIRED_KEYS + OPTIONAL_KEYS]
    if missing or unknown:
        raise GaitFileError(f'{label}: ' + '; '.join(
            ([f'missing {", ".join(missing)}'] if missing else [])
            + ([f'unknown key {", ".join(map(str, unknown))}'] if unknown else [])))
    groups_doc = doc['groups']
    if not isinstance(groups_doc, list) or not groups_doc:
        raise GaitFileError(f'{label}: groups must be a non-empty list of lists of legs')
    groups = tuple(_legs(g, f'{label}: groups') for g in groups_doc)
    flat = [leg for g in groups for leg in g]
    if sorted(flat) != list(range(len(LEGS))):
        raise GaitFileError(f'{label}: groups must hold each leg once, got {groups_doc}')
    if len({len(g) for g in groups}) != 1:
        raise GaitFileError(f'{label}: groups must be of one size (legs per step), got '
                            f'{groups_doc}')
    values = {}
    for key in NUMERIC_KEYS:
        if key not in doc:
            continue
        value = doc[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not math.isfinite(value) or value < 0:
            raise GaitFileError(f'{label}: {key} must be a finite number >= 0, got {value!r}')
        values[key] = float(value)
    if not values['swing_duration'] > 0:
        raise GaitFileError(f'{label}: swing_duration must be > 0')
    n = doc.get('n_footholds')
    if n is not None and (isinstance(n, bool) or not isinstance(n, int) or n < 1):
        raise GaitFileError(f'{label}: n_footholds must be an integer >= 1, got {n!r}')
    name = str(doc['name'])
    return GaitSpec(name, groups, values, n, str(doc.get('description', '')))


def load_gait_file(path: str | Path) -> GaitSpec:
    """Read and check one gait file."""
    path = Path(path)
    try:
        doc = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as err:
        raise GaitFileError(f'{path}: {err}') from err
    spec = parse_gait(doc, str(path))
    if spec.name != path.stem:
        raise GaitFileError(f'{path}: name {spec.name!r} is not the file name {path.stem!r}')
    return spec


def load_gait(name: str, config_dir: str | Path) -> GaitSpec:
    """The gait ``name`` of ``config_dir/gaits``."""
    return load_gait_file(gait_file_path(name, config_dir))
