"""The package map of docs/ARCHITECTURE.md ("Packages: the map"): what each sub-package of
replan_ros and each role of replan_core may import, checked on every import statement (at the
top of a module or inside a function), replan_core free of ROS and without import circles."""

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
# Role of replan_core -> the roles it may import, along the data's flow: the common base, the
# robot, then each stage (sensors and world, estimate, gait, MPC, controller); run metrics read
# recorded series only. Nothing but ``bench`` may import ``bench``.
CORE_ALLOWED = {
    'common': set(),
    'robot': {'common'},
    'sim': {'common', 'robot'},
    'estimation': {'common', 'robot'},
    'gait': {'common'},
    'mpc': {'common', 'gait'},
    'wbc': {'common', 'robot', 'gait'},
    'evaluation': {'common'},
    'bench': None,            # anything
}


def _imports(path: Path) -> list[str]:
    names = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            names += [node.module] + [f'{node.module}.{a.name}' for a in node.names]
        elif isinstance(node, ast.Import):
            names += [a.name for a in node.names]
    return names


def _part(path: Path, package: Path = PACKAGE) -> str:
    rel = path.relative_to(package)
    return rel.parts[0] if len(rel.parts) > 1 else rel.stem


def _module_name(path: Path, package: Path) -> str:
    parts = path.relative_to(package.parent).with_suffix('').parts
    return '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)


def _import_graph(package: Path) -> dict[str, set[str]]:
    """Module -> the modules of the same package it imports, each import statement resolved
    to the longest module name it names (``from a.b import c`` is ``a.b.c`` if that is a
    module, else ``a.b``)."""
    modules = {_module_name(p, package): p for p in package.rglob('*.py')}
    graph = {}
    for name, path in modules.items():
        targets = set()
        for imported in _imports(path):
            parts = imported.split('.')
            for end in range(len(parts), 0, -1):
                target = '.'.join(parts[:end])
                if target in modules:
                    if target != name:
                        targets.add(target)
                    break
        graph[name] = targets
    return graph


def _circle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import circle of ``graph`` (its nodes in order, the first again at the end), or
    None: a depth-first search that meets a node still on its path."""
    state: dict[str, int] = {}          # 1: on the path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for target in sorted(graph.get(node, ())):
            if state.get(target) == 1:
                return [*path[path.index(target):], target]
            if target not in state and (found := visit(target)):
                return found
        path.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


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


def test_the_core_root_holds_only_its_roles():
    modules = sorted(p.name for p in CORE.glob('*.py') if p.name != '__init__.py')
    packages = sorted(p.name for p in CORE.iterdir() if (p / '__init__.py').is_file())
    assert set(packages) == set(CORE_ALLOWED)
    assert modules == []


@pytest.mark.parametrize('path', sorted(p for p in CORE.rglob('*.py')
                                         if p != CORE / '__init__.py'),
                         ids=lambda p: str(p.relative_to(CORE)))
def test_each_core_module_imports_only_what_its_role_may(path):
    role = _part(path, CORE)
    allowed = CORE_ALLOWED[role]
    if allowed is None:
        return
    bad = sorted({name for name in _imports(path) if name.startswith('replan_core.')
                  and name.split('.')[1] not in allowed | {role}})
    assert not bad, f'{path.relative_to(CORE)} ({role}) imports {bad}'


def test_the_core_roles_follow_the_flow_without_a_circle():
    roles = {role: allowed or set() for role, allowed in CORE_ALLOWED.items()}
    assert _circle(roles) is None
    assert all('bench' not in allowed for allowed in roles.values())


def test_no_import_circle_between_core_modules():
    assert _circle(_import_graph(CORE)) is None


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
