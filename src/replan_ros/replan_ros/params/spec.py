"""Parameter specs and value checks: ``ParamSpec`` (one parameter's default, unit, range,
choices, list length, read-only flag and string syntax), the kinds a value may have, the
``ConfigError`` every check raises, and ``check_value``, which coerces a value to its spec's kind
or says in words why it is not allowed (``is out of range [1, 8]``); the other modules of
``replan_ros.params`` build their tables, file checks and node declarations on these. Standard
library only: importing it loads nothing of the core.
"""

from __future__ import annotations

import difflib
import json
import math
import re
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

INF = math.inf
# Declared by rclpy itself in every node; allowed in every section.
BUILTIN = {'use_sim_time': bool, 'start_type_description_service': bool}
KINDS = ('bool', 'int', 'float', 'str', 'bool[]', 'int[]', 'float[]', 'str[]')
_SYNTAXES = {'': '', 'regex': 'a Python regular expression', 'json_object': 'a JSON object'}
_KIND_NAMES = {'bool': 'a bool', 'int': 'an int', 'float': 'a float (an int is accepted)',
               'str': 'a string', 'bool[]': 'a list of bools', 'int[]': 'a list of ints',
               'float[]': 'a list of floats (ints accepted)', 'str[]': 'a list of strings'}
RESTART_HINT = 'read once at start: change it in a parameter file and restart the node'


class ConfigError(ValueError):
    """A parameter file or value that must not start: one line, without 'config error: '."""


def _kind_of(value: Any) -> str:
    if isinstance(value, bool):
        return 'bool'
    if isinstance(value, int):
        return 'int'
    if isinstance(value, float):
        return 'float'
    if isinstance(value, str):
        return 'str'
    if isinstance(value, (list, tuple)) and value:
        return _kind_of(value[0]) + '[]'
    raise ValueError(f'cannot infer the kind of {value!r}: give kind=')


@dataclass(frozen=True)
class ParamSpec:
    """One parameter: ``min``/``max`` bound a number or each element of a list; ``length``
    fixes a list's length; ``choices`` are the allowed strings (or list elements)."""

    name: str
    default: Any
    description: str
    unit: str = ''
    min: float | None = None
    max: float | None = None
    choices: tuple = ()
    read_only: bool = True
    length: int | None = None
    kind: str = ''
    syntax: str = ''          # a string's syntax when not empty: 'regex' or 'json_object'

    def __post_init__(self) -> None:
        if not self.kind:
            object.__setattr__(self, 'kind', _kind_of(self.default))
        if isinstance(self.default, tuple):
            object.__setattr__(self, 'default', list(self.default))
        assert self.kind in KINDS, self.kind
        assert self.syntax in _SYNTAXES, self.syntax

    @property
    def is_list(self) -> bool:
        return self.kind.endswith('[]')

    @property
    def element(self) -> str:
        return self.kind.removesuffix('[]')

    def allowed(self) -> str:
        """What the parameter accepts, in words."""
        parts = [_KIND_NAMES[self.kind]]
        if self.length is not None:
            parts.append(f'of {self.length} values')
        if self.choices:
            parts.append('one of ' + ', '.join(map(str, self.choices)))
        if self.syntax:
            parts.append(_SYNTAXES[self.syntax])
        if self.min is not None or self.max is not None:
            parts.append(f'in {self.range_text()}')
        return ' '.join(parts)

    def range_text(self) -> str:
        lo = '-inf' if self.min is None else _fmt(self.min)
        hi = 'inf' if self.max is None else _fmt(self.max)
        return f'[{lo}, {hi}]'

    def full_description(self) -> str:
        text = self.description + (f' [{self.unit}]' if self.unit else '')
        return text + (f' (read-only: {RESTART_HINT})' if self.read_only else '')


def _fmt(value: Any) -> str:
    """A value as the user wrote it (YAML-like)."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float) and value.is_integer() and abs(value) < 1e15:
        return repr(value)
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, (list, tuple)):
        return '[' + ', '.join(_fmt(v) for v in value) + ']'
    return str(value)



def _suggest(name: str, known: Iterable[str]) -> str:
    close = difflib.get_close_matches(name, list(known), n=1, cutoff=0.6)
    return f' (did you mean {close[0]}?)' if close else ''


def _check_element(spec: ParamSpec, value: Any, kind: str) -> tuple[Any, str | None]:
    """(coerced value, None) or (value, reason) for one scalar of ``kind``."""
    if kind == 'bool':
        ok = isinstance(value, bool)
    elif kind == 'int':
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif kind == 'float':
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        if ok:
            value = float(value)        # ROS's rule: an int is accepted for a float
            if not math.isfinite(value):
                return value, 'is not finite'
    else:
        ok = isinstance(value, str)
    if not ok:
        return value, f'has the wrong type: expected {_KIND_NAMES[spec.kind]}'
    if spec.choices and value not in spec.choices:
        return value, 'is not one of ' + ', '.join(map(str, spec.choices))
    if spec.syntax and value:
        reason = _syntax_error(spec.syntax, value)
        if reason:
            return value, reason
    if kind in ('int', 'float') and (
            (spec.min is not None and value < spec.min)
            or (spec.max is not None and value > spec.max)):
        return value, f'is out of range {spec.range_text()}'
    return value, None


def _syntax_error(syntax: str, text: str) -> str | None:
    """Why ``text`` is not a valid ``syntax`` string, or None."""
    if syntax == 'regex':
        try:
            re.compile(text)
        except re.error as err:
            return f'is not a valid regular expression ({err})'
        return None
    try:
        parsed = json.loads(text)
    except ValueError as err:
        return f'is not valid JSON ({err})'
    return None if isinstance(parsed, dict) else 'is not a JSON object ({...})'


def check_value(spec: ParamSpec, value: Any) -> Any:
    """The value, coerced to the spec's kind (int -> float); ConfigError with the reason."""
    if spec.is_list:
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f'has the wrong type: expected {_KIND_NAMES[spec.kind]}')
        if spec.length is not None and len(value) != spec.length:
            raise ConfigError(f'has {len(value)} values: expected {spec.length}')
        out = []
        for item in value:
            item, reason = _check_element(spec, item, spec.element)
            if reason:
                raise ConfigError(f'has an element {_fmt(item)} that {reason}')
            out.append(item)
        return out
    value, reason = _check_element(spec, value, spec.kind)
    if reason:
        raise ConfigError(reason)
    return value
