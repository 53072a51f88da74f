"""The package map of docs/ARCHITECTURE.md ("Packages: the map"), checked on every import
statement, those inside functions too: what each sub-package of replan_ros and each role of
replan_core may import; replan_core free of ROS; the runtime packages (replan_core,
replan_ros, their tests) free of replan_experiments, matplotlib and Ray; no import circle in
any of the three packages."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2]
PACKAGE = SRC / 'replan_ros' / 'replan_ros'
CORE = SRC / 'replan_core' / 'replan_core'
EXPERIMENTS = SRC / 'replan_experiments' / 'replan_experiments'
PACKAGES = {'replan_core': CORE, 'replan_ros': PACKAGE, 'replan_experiments': EXPERIMENTS}
# Sub-package -> the replan_ros parts it may import.
ALLOWED = {
    'messages': set(), 'transport': set(), 'telemetry': set(), 'params': set(),
    'recording': {'messages'},
    'view': {'messages', 'transport', 'params', 'recording', 'nodes.node_main'},
    'nodes': {'messages', 'transport', 'telemetry', 'params', 'recording', 'view'},
    'launch': {'transport', 'params'},
    'tools': {'messages', 'transport', 'params', 'recording', 'launch'},
}
# What only the experiments may use: a node, a tool or a runtime test that imports one of these
# would need the plotting and cluster dependencies to run the robot.
RUNTIME_FORBIDDEN = ('replan_experiments', 'matplotlib', 'ray')
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
    """Every name an import statement of ``path`` names, the module's and ``module.name``."""
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


def _modules() -> dict[str, Path]:
    """Dotted module name -> file, of the three packages (a package is its __init__.py)."""
    out = {}
    for root in PACKAGES.values():
        for path in root.rglob('*.py'):
            rel = path.relative_to(root.parent).with_suffix('')
            parts = rel.parts[:-1] if rel.name == '__init__' else rel.parts
            out['.'.join(parts)] = path
    return out


def _module_imports(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The modules of the three packages that ``name`` imports (relative imports resolved;
    ``from package import module`` is the module, ``from module import name`` the module)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            base = node.module or ''
            if node.level:
                here = name.split('.') if path.name == '__init__.py' else name.split('.')[:-1]
                here = here[:len(here) - node.level + 1]
                base = '.'.join([*here, base] if base else here)
            for alias in node.names:
                full = f'{base}.{alias.name}'
                out.add(full if full in modules else base)
        elif isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
    return {target for target in out if target in modules and target != name}


def import_circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The groups of two or more modules that import each other, directly or through others
    (the strongly connected components of ``graph``, iterative Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    circles = []
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, targets = work[-1]
            target = next(targets, None)
            if target is not None:
                if target not in index:
                    index[target] = low[target] = len(index)
                    stack.append(target)
                    on_stack.add(target)
                    work.append((target, iter(sorted(graph.get(target, ())))))
                elif target in on_stack:
                    low[node] = min(low[node], index[target])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                group = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    group.append(member)
                    if member == node:
                        break
                if len(group) > 1:
                    circles.append(sorted(group))
    return circles


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
    assert import_circles(roles) == []
    assert all('bench' not in allowed for allowed in roles.values())


# The roles whose settings (the dataclasses a node fills from its parameters) live beside heavy
# modules keep them in a light ``settings`` module, which the parameter tables import.
CORE_SETTINGS = ('sim', 'estimation', 'mpc', 'wbc')


@pytest.mark.parametrize('role', CORE_SETTINGS)
def test_each_role_settings_module_is_light(role):
    """Standard library and numpy only, so that the parameter tables can import it
    (test_params checks in a fresh process what importing ``replan_ros.params`` loads)."""
    path = CORE / role / 'settings.py'
    roots = {name.split('.')[0] for name in _imports(path)}
    heavy = roots - set(sys.stdlib_module_names) - {'__future__', 'numpy', 'replan_core'}
    assert not heavy, f'{path.relative_to(CORE)} imports {sorted(heavy)}'


def test_the_core_imports_no_ros():
    for path in CORE.rglob('*.py'):
        for name in _imports(path):
            root = name.split('.')[0]
            assert root not in ('rclpy', 'replan_ros', 'replan_experiments') \
                and not root.endswith('_msgs'), f'{path.name} imports {name}'


def test_the_runtime_packages_and_their_tests_import_no_experiment_code():
    bad = []
    for package in ('replan_core', 'replan_ros'):
        for path in sorted((SRC / package).rglob('*.py')):
            names = {name.split('.')[0] for name in _imports(path)}
            bad += [f'{path.relative_to(SRC)}: {name}'
                    for name in sorted(names & set(RUNTIME_FORBIDDEN))]
    assert not bad, '\n'.join(bad)


def test_no_import_circle_in_any_package():
    modules = _modules()
    graph = {name: _module_imports(name, path, modules) for name, path in modules.items()}
    circles = import_circles(graph)
    assert not circles, '\n'.join(' <-> '.join(group) for group in circles)


def test_the_circle_finder_finds_circles_through_other_modules():
    graph = {'a': {'b'}, 'b': {'c'}, 'c': {'a', 'd'}, 'd': set(), 'e': {'e', 'd'}}
    assert import_circles(graph) == [['a', 'b', 'c']]
    assert import_circles({'a': {'b'}, 'b': set()}) == []


NODE_LINES = 400        # a node converts messages, calls the core and publishes
MODULE_LINES = 700


def test_nodes_stay_thin_and_modules_readable():
    too_long = []
    for path in sorted(p for root in PACKAGES.values() for p in root.rglob('*.py')):
        lines = len(path.read_text().splitlines())
        limit = NODE_LINES if path.name.endswith('_node.py') else MODULE_LINES
        if lines > limit:
            too_long.append(f'{path.relative_to(SRC)}: {lines} lines (at most {limit})')
    assert not too_long, '\n'.join(too_long)
