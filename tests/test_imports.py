"""The workspace's import graph, read with ast (nothing is imported or run): no import cycle
between modules, no package importing one it must not know (a layer above it, or beside it),
and every workspace package a module imports declared in its package.xml.

Imports inside functions count: a lazy import is a dependency all the same, and it is how a
cycle hides (bag_reading and bag_recover once imported each other that way).
"""

import ast
from pathlib import Path
import xml.etree.ElementTree as ElementTree

SRC = Path(__file__).resolve().parents[1] / 'ros2_ws' / 'src'  # no ROS needed to read it
# The layers, lowest first, and what each package may import of the others: anything below
# it, except that the agent and the tools stand alone on the messages (the agent works with
# any environment that speaks rl_msgs; the tools record and replay any graph), that the world
# model (stealth_core) stands at the bottom, plain Python that imports no ROS at all, and that the
# experiments, on top, use no ROS of their own: they train the agent's learners on the
# environment in-process, write with bringup's run outputs, and run ROS trials as bringup's
# `stealth train`.
LAYERS = (
    'stealth_core',
    'stealth_interfaces',
    'stealth_node_kit',
    'stealth_sim',
    'stealth_env',
    'stealth_agent',
    'stealth_nav2',
    'stealth_learn',
    'stealth_tools',
    'stealth_bringup',
    'stealth_experiments',
)
MAY_IMPORT = {
    'stealth_core': set(),  # no workspace package, and no ROS (ROS_MODULES below)
    'stealth_interfaces': set(),
    'stealth_node_kit': set(),  # what every node shares: rclpy only
    'stealth_sim': {'stealth_core', 'stealth_interfaces', 'stealth_node_kit'},
    # The environment node drives any robot through the messages; only its tests start the
    # simulator's physics in-process (test_depend).
    'stealth_env': {'stealth_core', 'stealth_interfaces', 'stealth_node_kit', 'stealth_sim'},
    # The agent reads the grid observation's cells (stealth_core.grid_cells), nothing else of
    # the world model.
    'stealth_agent': {'stealth_core', 'stealth_interfaces', 'stealth_node_kit'},
    # Nav2's interfaces over the world model (planners, light model), the environment node's
    # robot over topics (the navigator drives it) and the agent's policies (the learned policy
    # as a planner id).
    'stealth_nav2': {
        'stealth_core',
        'stealth_interfaces',
        'stealth_node_kit',
        'stealth_env',
        'stealth_agent',
    },
    # Learning across buildings: the world model (tables from its lattice model), no ROS.
    'stealth_learn': {'stealth_core'},
    'stealth_tools': {'stealth_interfaces', 'stealth_node_kit'},
    'stealth_bringup': set(LAYERS) - {'stealth_bringup', 'stealth_experiments'},
    # The benchmark's generalist method plays stealth_learn's agent (imported in that method only).
    'stealth_experiments': {
        'stealth_core',
        'stealth_agent',
        'stealth_learn',
        'stealth_tools',
        'stealth_bringup',
    },
}
# Tests that reach up on purpose, each with why; any other test import is held to the rules.
TEST_EXCEPTIONS: dict[str, tuple[str, str]] = {}  # {test file: (package, why)}
# What the world model must never import, even lazily: ROS's client library and any message or
# interface package (their names end so), so that it installs and runs without ROS.
ROS_MODULES = ('rclpy', 'rosidl_runtime_py', 'rosidl_parser', 'ament_index_python', 'launch')
ROS_SUFFIXES = ('_msgs', '_srvs', '_interfaces')
RUN_DEPENDS = ('depend', 'exec_depend')
TEST_DEPENDS = (*RUN_DEPENDS, 'test_depend')


def workspace_packages(src: Path) -> dict[str, Path]:
    """{package name: its directory} of every package.xml under src."""
    packages = {}
    for manifest in sorted(src.rglob('package.xml')):
        name = ElementTree.parse(manifest).getroot().findtext('name').strip()
        packages[name] = manifest.parent
    return packages


def declared(package_dir: Path, kinds: tuple[str, ...]) -> set[str]:
    root = ElementTree.parse(package_dir / 'package.xml').getroot()
    return {element.text.strip() for kind in kinds for element in root.iter(kind)}


def python_files(package_dir: Path, package: str) -> dict[str, Path]:
    """{module name: file} of the package's Python package and of its tests ('test.<name>')."""
    modules = {}
    for path in sorted((package_dir / package).rglob('*.py')):
        parts = path.relative_to(package_dir).with_suffix('').parts
        modules['.'.join(parts[:-1] if parts[-1] == '__init__' else parts)] = path
    for path in sorted((package_dir / 'test').glob('*.py')):
        modules[f'{package}/test.{path.stem}'] = path
    return modules


def excepted(src: Path, path: Path, imported: str) -> bool:
    exception = TEST_EXCEPTIONS.get(str(path.relative_to(src)))
    return exception is not None and exception[0] == imported


def imported_names(module: str, path: Path) -> list[tuple[str, int]]:
    """(dotted name, line) of everything the file imports, `from a import b` as 'a.b' too."""
    names = []
    package_parts = module.split('.')[: -1 if path.name != '__init__.py' else None]
    for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'), str(path))):
        if isinstance(node, ast.Import):
            names += [(alias.name, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base_parts = package_parts[: len(package_parts) - node.level + 1] if node.level else []
            base = '.'.join([*base_parts, *([node.module] if node.module else [])])
            names.append((base, node.lineno))
            names += [(f'{base}.{alias.name}', node.lineno) for alias in node.names]
    return names


def module_graph(src: Path) -> dict[str, set[str]]:
    """{module: the workspace modules it imports}, tests left out (nothing imports them)."""
    modules = {}
    for package, directory in workspace_packages(src).items():
        modules.update(
            (name, path)
            for name, path in python_files(directory, package).items()
            if '/' not in name
        )
    graph = {}
    for module, path in modules.items():
        graph[module] = {
            name for name, _ in imported_names(module, path) if name in modules and name != module
        }
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Every strongly connected set of two or more modules (Tarjan), each sorted."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for successor in sorted(graph[node]):
            if successor not in index:
                visit(successor)
                low[node] = min(low[node], low[successor])
            elif successor in on_stack:
                low[node] = min(low[node], index[successor])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def forbidden_imports(src: Path) -> list[str]:
    """'file:line: what is wrong' for each import of a package the importer must not know."""
    problems = []
    packages = workspace_packages(src)
    for package, directory in packages.items():
        if package not in MAY_IMPORT:
            continue
        for module, path in python_files(directory, package).items():
            for name, line in imported_names(module, path):
                top = name.split('.')[0]
                if top == package or top not in MAY_IMPORT or top in MAY_IMPORT[package]:
                    continue
                if excepted(src, path, top):
                    continue
                above = LAYERS.index(top) > LAYERS.index(package)
                where = 'a layer above it' if above else 'which it must not know'
                problems.append(
                    f'{path.relative_to(src)}:{line}: {package} imports {top}, {where}'
                )
    return sorted(set(problems))


def undeclared_imports(src: Path) -> list[str]:
    """'file:line: ...' for each import of a workspace package its package.xml does not list."""
    problems = []
    packages = workspace_packages(src)
    for package, directory in packages.items():
        runs, tests = declared(directory, RUN_DEPENDS), declared(directory, TEST_DEPENDS)
        for module, path in python_files(directory, package).items():
            allowed = tests if '/' in module else runs
            kind = 'test_depend' if '/' in module else 'exec_depend'
            for name, line in imported_names(module, path):
                top = name.split('.')[0]
                if top == package or top not in packages or top in allowed:
                    continue
                if not excepted(src, path, top):
                    where = f'{path.relative_to(src)}:{line}'
                    problems.append(f'{where}: imports {top}, not an {kind} of {package}')
    return sorted(set(problems))


def ros_imports(src: Path, package: str) -> list[str]:
    """'file:line: imports X' for each ROS import of the package's modules and tests."""
    problems = []
    directory = workspace_packages(src)[package]
    for module, path in python_files(directory, package).items():
        for name, line in imported_names(module, path):
            top = name.split('.')[0]
            if top in ROS_MODULES or top.endswith(ROS_SUFFIXES):
                problems.append(f'{path.relative_to(src)}:{line}: imports {top}')
    return sorted(set(problems))


def test_the_world_model_imports_no_ros():
    assert len(python_files(workspace_packages(SRC)['stealth_core'], 'stealth_core')) > 30
    assert ros_imports(SRC, 'stealth_core') == []


def test_the_ros_check_finds_ros_imports():
    # the rule above can fail: the environment node's package is full of them
    found = ros_imports(SRC, 'stealth_env')
    assert any(line.endswith('imports rclpy') for line in found)
    assert any(line.endswith('imports stealth_interfaces') for line in found)


def test_every_stealth_package_has_a_layer():
    stealth = {name for name in workspace_packages(SRC) if name.startswith('stealth_')}
    assert stealth == set(LAYERS)


def test_no_module_import_cycle():
    graph = module_graph(SRC)
    assert len(graph) > 50  # the walk found the modules
    assert cycles(graph) == []


def test_no_package_imports_one_it_must_not_know():
    assert forbidden_imports(SRC) == []


def test_every_imported_workspace_package_is_declared():
    assert undeclared_imports(SRC) == []
