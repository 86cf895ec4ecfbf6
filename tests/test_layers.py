"""The folders show the pipeline, and the code keeps to it.

Modules are ordered in layers, from the simulator up to the ROS nodes: a module
imports modules of its own layer or of the layers below it, never one above.
Layers named side by side (graph and study) do not import each other. No two
modules import each other, directly or through others. The README's layout table
lists exactly the folders that exist.

A new subpackage gets its place in :data:`LAYERS` (and a row in the README).
"""

from __future__ import annotations

import ast
import re
import subprocess
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SRC = ROOT / "src"
PYTHON_PACKAGES = ("sdbc_sim", "sdbc_evolution")
"""The workspace's Python packages (src/<name>/<name>)."""

LAYERS: tuple[tuple[str, ...], ...] = (
    ("sdbc_sim",),
    ("sdbc_sim.nodes",),
    ("sdbc_evolution.sdbc",),
    ("sdbc_evolution.characterise",),
    ("sdbc_evolution.relevance",),
    ("sdbc_evolution.transforms",),
    ("sdbc_evolution.ga",),
    ("sdbc_evolution.run",),
    ("sdbc_evolution.graph", "sdbc_evolution.study"),
    # sdbc-conformance: a task's checks, and a running simulator's through the
    # graph (--live).
    ("sdbc_evolution.conformance",),
    ("sdbc_evolution.nodes",),
    # The package's own __init__: the curated front (NoveltySearch and the few
    # names a researcher needs), loaded lazily from the layers below it; no module
    # of the package imports it.
    ("sdbc_evolution",),
)
"""Bottom first. A module belongs to the longest prefix that names it; a prefix
may name a folder that does not exist (yet). Prefixes of one entry are side by
side: none imports another. The entry ``sdbc_evolution`` alone is the package's
``__init__``, which re-exports from below it."""
SIDE_BY_SIDE_EXEMPT = {"sdbc_evolution"}
"""Prefixes exempt from the side-by-side rule: the top-level package."""


def module_name(path: Path) -> str:
    """``src/sdbc_sim/sdbc_sim/nodes/interface.py`` -> ``sdbc_sim.nodes.interface``
    (a package's ``__init__`` is the package)."""
    for package in PYTHON_PACKAGES:
        root = SRC / package
        if root in path.parents:
            relative = path.relative_to(root).with_suffix("")
            names = list(relative.parts)
            if names[-1] == "__init__":
                names.pop()
            return ".".join(names)
    raise ValueError(f"{path} is in no workspace package")


def project_modules() -> dict[str, Path]:
    """Every module of the workspace's Python packages, by dotted name."""
    modules = {}
    for package in PYTHON_PACKAGES:
        for path in sorted((SRC / package / package).rglob("*.py")):
            modules[module_name(path)] = path
    return modules


def imports(path: Path, name: str, known: set[str]) -> Iterator[tuple[str, int]]:
    """The project modules that ``path`` (module ``name``) imports, anywhere in it
    (inside functions and ``TYPE_CHECKING`` too: a dependency all the same),
    with the line of each import."""
    is_package = path.name == "__init__.py"
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".")
                # A package's __init__ is its own package for relative imports.
                base = base[: len(base) - node.level + (1 if is_package else 0)]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            # ``from package import module`` names a module; otherwise a name.
            targets = [
                f"{module}.{alias.name}"
                if f"{module}.{alias.name}" in known
                else module
                for alias in node.names
            ]
        for target in targets:
            # The deepest project module the import names.
            while target and target not in known:
                target = target.rpartition(".")[0]
            if target and target != name:
                yield target, node.lineno


def layer_of(module: str) -> tuple[int, str]:
    """The layer index and the prefix that places ``module``."""
    best: tuple[int, str] | None = None
    for index, prefixes in enumerate(LAYERS):
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".")) and (
                best is None or len(prefix) > len(best[1])
            ):
                best = (index, prefix)
    if best is None:
        raise AssertionError(f"module {module} is in no layer: add it to LAYERS")
    return best


def import_graph() -> dict[str, dict[str, int]]:
    modules = project_modules()
    known = set(modules)
    return {name: dict(imports(path, name, known)) for name, path in modules.items()}


def layer_violations(graph: dict[str, dict[str, int]]) -> list[str]:
    """Imports that go up a layer or across to a layer side by side, as
    ``module:line: ...``."""
    problems = []
    for name, targets in graph.items():
        layer, prefix = layer_of(name)
        for target, line in targets.items():
            target_layer, target_prefix = layer_of(target)
            upward = target_layer > layer
            across = (
                target_layer == layer
                and target_prefix != prefix
                and not {prefix, target_prefix} & SIDE_BY_SIDE_EXEMPT
            )
            if upward or across:
                problems.append(
                    f"{name}:{line}: ({prefix}) imports {target} "
                    f"({target_prefix}), {'a layer above' if upward else 'beside it'}"
                )
    return problems


def cycles(graph: dict[str, dict[str, int]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for target in graph.get(node, {}):
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in on_stack:
                low[node] = min(low[node], index[target])
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


def test_no_module_imports_a_layer_above_it_or_beside_it():
    problems = layer_violations(import_graph())
    assert not problems, "\n".join(problems)


def test_no_import_cycles():
    found = cycles(import_graph())
    assert not found, "import cycles: " + "; ".join(" <-> ".join(c) for c in found)


def test_the_checks_see_violations_and_cycles():
    graph = {
        "sdbc_sim.engine": {"sdbc_evolution.run.config": 3},
        "sdbc_evolution.run.config": {"sdbc_evolution.ga.archive": 1},
        "sdbc_evolution.ga.archive": {},
        "sdbc_evolution.graph.launch": {"sdbc_evolution.study.cli": 7},
        "sdbc_evolution.study.cli": {"sdbc_evolution.study.report": 1},
        "sdbc_evolution.study.report": {"sdbc_evolution.study.cli": 2},
    }
    assert layer_violations(graph) == [
        "sdbc_sim.engine:3: (sdbc_sim) imports sdbc_evolution.run.config "
        "(sdbc_evolution.run), a layer above",
        "sdbc_evolution.graph.launch:7: (sdbc_evolution.graph) imports "
        "sdbc_evolution.study.cli (sdbc_evolution.study), beside it",
    ]
    assert cycles(graph) == [
        ["sdbc_evolution.study.cli", "sdbc_evolution.study.report"]
    ]


# --- the README's layout table -------------------------------------------------

LAYOUT_HEADING = "## Layout"


def tracked_folders() -> set[str]:
    """The folders the layout table must list: the repository's top-level folders
    but ``src/``, the ROS packages in it (``src/sdbc_sim/``), and the stages of
    their Python packages, the subpackages one level down, by import path
    (``sdbc_sim/tasks/``; what a stage holds in folders of its own is its
    business)."""
    files = subprocess.run(
        ["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout.split()
    folders = {f.split("/")[0] + "/" for f in files if "/" in f} - {"src/"}
    for f in files:
        parts = f.split("/")
        if parts[0] != "src" or len(parts) < 3:
            continue
        folders.add(f"src/{parts[1]}/")
        # src/<pkg>/<pkg>/<sub>/__init__.py -> <pkg>/<sub>/
        if parts[-1] == "__init__.py" and len(parts) == 5 and parts[1] == parts[2]:
            folders.add("/".join(parts[2:4]) + "/")
    return folders


def readme_layout_folders() -> list[str]:
    """The first column of the README's layout table."""
    text = (ROOT / "README.md").read_text()
    section = text.split(LAYOUT_HEADING + "\n", 1)
    assert len(section) == 2, f"README.md has no '{LAYOUT_HEADING}' section"
    body = section[1].split("\n## ", 1)[0]
    return re.findall(r"^\| `([^`]+)` \|", body, flags=re.MULTILINE)


def test_the_readme_layout_table_lists_exactly_the_folders_that_exist():
    listed = readme_layout_folders()
    assert len(listed) == len(set(listed)), f"listed twice: {listed}"
    existing = tracked_folders()
    assert set(listed) == existing, (
        f"missing from the table: {sorted(existing - set(listed))}; "
        f"in the table but absent: {sorted(set(listed) - existing)}"
    )
