"""The package map of docs/ARCHITECTURE.md ("Packages: the map"): what each sub-package of
replan_ros may import, checked on every import statement, and replan_core free of ROS."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2]
PACKAGE = SRC / 'replan_ros' / 'replan_ros'
CORE = SRC / 'replan_core' / 'replan_core'
# Sub-package -> the replan_ros parts it may import.
ALLOWED = {
    'messages': set(), 'transport': set(), 'telemetry': set(), 'params': set(),
    'recording': set(),
    'view': {'messages', 'transport', 'params', 'recording', 'nodes.node_main'},
    'nodes': {'messages', 'transport', 'telemetry', 'params', 'recording', 'view'},
    'launch': {'transport', 'params'},
    'tools': {'messages', 'transport', 'params', 'recording', 'launch'},
    'experiments': {'messages', 'params', 'recording', 'launch', 'tools'},
    'benchmarks': None,       # anything
}


def _imports(path: Path) -> list[str]:
    names = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            names += [node.module] + [f'{node.module}.{a.name}' for a in node.names]
        elif isinstance(node, ast.Import):
            names += [a.name for a in node.names]
    return names


def _part(path: Path) -> str:
    rel = path.relative_to(PACKAGE)
    return rel.parts[0] if len(rel.parts) > 1 else rel.stem


def test_the_root_holds_only_the_sub_packages():
    modules = sorted(p.name for p in PACKAGE.glob('*.py') if p.name != '__init__.py')
    packages = sorted(p.name for p in PACKAGE.iterdir() if (p / '__init__.py').is_file())
    assert set(packages) == set(ALLOWED)
    assert modules == []


@pytest.mark.parametrize('path', sorted(p for p in PACKAGE.rglob('*.py')
                                         if p != PACKAGE / '__init__.py'),
                         ids=lambda p: str(p.relative_to(PACKAGE)))
def test_each_module_imports_only_what_its_package_may(path):
    part = _part(path)
    allowed = ALLOWED[part]
    if allowed is None:
        return
    bad = []
    for name in _imports(path):
        if not name.startswith('replan_ros.'):
            continue
        target = name.split('.')[1]
        if target == part or target in allowed or '.'.join(name.split('.')[1:3]) in allowed:
            continue
        bad.append(name)
    assert not bad, f'{path.name} ({part}) imports {sorted(set(bad))}'


def test_the_core_imports_no_ros():
    for path in CORE.rglob('*.py'):
        for name in _imports(path):
            root = name.split('.')[0]
            assert root not in ('rclpy', 'replan_ros') and not root.endswith('_msgs'), \
                f'{path.name} imports {name}'


NODE_LINES = 400        # a node converts messages, calls the core and publishes
MODULE_LINES = 700


def test_nodes_stay_thin_and_modules_readable():
    too_long = []
    for path in sorted([*PACKAGE.rglob('*.py'), *CORE.rglob('*.py')]):
        lines = len(path.read_text().splitlines())
        limit = NODE_LINES if path.name.endswith('_node.py') else MODULE_LINES
        if lines > limit:
            too_long.append(f'{path.relative_to(SRC)}: {lines} lines (at most {limit})')
    assert not too_long, '\n'.join(too_long)
