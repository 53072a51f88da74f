"""The package map of docs/ARCHITECTURE.md ("Packages: the map"): what each sub-package of
replan_ros may import, checked on every import statement, and replan_core free of ROS."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2]
PACKAGE = SRC / 'replan_ros' / 'replan_ros'
CORE = SRC / 'replan_core' / 'replan_core'
# Sub-package (or root module) -> the replan_ros parts it may import.
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


def test_the_root_holds_sub_packages_and_a_handful_of_modules():
    modules = sorted(p.name for p in PACKAGE.glob('*.py') if p.name != '__init__.py')
    packages = sorted(p.name for p in PACKAGE.iterdir() if (p / '__init__.py').is_file())
    assert set(packages) == set(ALLOWED) - {'params'}
    assert modules == ['params.py']


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
