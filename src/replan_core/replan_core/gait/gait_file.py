"""Gaits as data: one YAML file per gait, ``config/gaits/<name>.yaml`` (docs/gait.md, "Gait files").

A gait file says which legs swing together and in what order (``groups``: the crawl one leg at a
time, a trot the diagonal pairs), the swing and all-feet-down durations, the step height, the
step and set-point limits, the steps per plan, and the width of the MPC's line support for two
feet. Its times, lengths and speeds are the reference robot's (``config/robots/scaling.yaml``,
``reference``: HyQ), in s, m, m/s and rad/s, and scale to another robot by the existing rules
(docs/robot_files.md, "Scaling rules"): times with sqrt(l / g), lengths with l, speeds with
sqrt(g l), turn rates with sqrt(g / l). The caller (which knows the robot) passes the ratios;
for the reference robot they are 1.0 and the values come out unchanged, bit for bit (so
``crawl.yaml`` gives exactly ``GaitParams()``'s crawl).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import yaml

from replan_core.common.types import LEGS
from replan_core.gait.crawl import GaitParams

# Each numeric key of a gait file, the scaling rule it follows (scaling.yaml's rule names).
SCALED_KEYS: dict[str, str] = {
    'swing_duration': 'time',            # s
    'four_feet_duration': 'time',        # s
    'idle_after': 'time',                # s
    'idle_replan_period': 'time',        # s
    'step_height': 'length',             # m
    'max_step_length_x': 'length',       # m
    'max_step_length_y': 'length',       # m
    'line_support_width': 'length',      # m, the MPC's (MpcSettings.line_support_width)
    'max_linear_x': 'speed',             # m/s
    'max_linear_y': 'speed',             # m/s
    'max_angular_z': 'rate',             # rad/s
}
REQUIRED_KEYS = ('name', 'groups', 'swing_duration', 'four_feet_duration')
OPTIONAL_KEYS = ('description', 'n_footholds', *(k for k in SCALED_KEYS
                                                   if k not in REQUIRED_KEYS))
RULES = ('time', 'length', 'speed', 'rate')


class GaitFileError(ValueError):
    """A gait file that cannot be used: the message names the file and the key."""


@dataclass(frozen=True)
class GaitSpec:
    """One gait file, in the reference robot's units."""

    name: str
    groups: tuple[tuple[int, ...], ...]      # leg indices (LEGS) per step, in swing order
    values: Mapping[str, float]              # the SCALED_KEYS given in the file
    n_footholds: int | None = None           # steps (groups) per plan; None: the base's
    description: str = ''

    @property
    def sequence(self) -> tuple[int, ...]:
        """The legs in swing order (GaitParams.sequence)."""
        return tuple(leg for group in self.groups for leg in group)

    def scaled(self, scales: Mapping[str, float] | None = None) -> dict[str, float]:
        """The file's values for a robot: each times its rule's ratio (robot / reference)."""
        scales = scales or {}
        unknown = set(scales) - set(RULES)
        if unknown:
            raise ValueError(f'unknown scaling rules {sorted(unknown)}; known: {RULES}')
        return {key: value * float(scales.get(SCALED_KEYS[key], 1.0))
                for key, value in self.values.items()}

    def params(self, base: GaitParams | None = None,
               scales: Mapping[str, float] | None = None) -> GaitParams:
        """``base`` (default ``GaitParams()``) with this gait's groups, times and limits."""
        base = GaitParams() if base is None else base
        values = self.scaled(scales)
        values.pop('line_support_width', None)       # the MPC's, not the gait's
        groups = self.groups if any(len(g) > 1 for g in self.groups) else ()
        params = replace(base, sequence=self.sequence, groups=groups, **values)
        if self.n_footholds is not None:
            params = replace(params, n_footholds=self.n_footholds)
        params.validate()
        return params

    def line_support_width(self, scales: Mapping[str, float] | None = None) -> float:
        """m, the MPC's line support width for this gait (0: no two-feet support)."""
        return self.scaled(scales).get('line_support_width', 0.0)


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
    values = {}
    for key in SCALED_KEYS:
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
