"""The packages form layers without cycles (read from the source with ``ast``; nothing is imported).

Layers, bottom to top: physics -> batch -> flagellum_env -> agents -> flagellum_bench (benchmarks) -> flagellum
(the CLI). A module
may import its own package and the layers below it, never one above; and no two files import each
other, directly or round a longer loop (imports inside functions count: they are cycles at run time). A string
naming an entry point (``"package.module:Name"``, as ``gymnasium.register`` takes) is a reference to that module
too: it may not point up a layer (it is loaded later, so it is not part of a cycle).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
LAYERS = ("physics", "batch", "flagellum_env", "agents", "experiments", "flagellum_bench", "flagellum")

#: File cycles that exist on purpose for now, each with the reason it stays.
KNOWN_CYCLES: set[frozenset[str]] = set()


def module_files() -> dict[str, Path]:
    """Every module of the layered packages: dotted name -> file."""
    out = {}
    for pkg in LAYERS:
        for f in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(f.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            out[".".join(parts)] = f
    return out


def imported_modules(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The modules of ``modules`` that ``name`` imports anywhere in its file (top level or inside functions)."""
    is_pkg = path.name == "__init__.py"
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".")
                base = base[:len(base) - node.level + (1 if is_pkg else 0)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            targets = [mod] + [f"{mod}.{a.name}" for a in node.names]
        for t in targets:
            # "import a.b.c" imports a.b.c (resolve to the longest known module)
            parts = t.split(".")
            while parts and ".".join(parts) not in modules:
                parts.pop()
            if parts and ".".join(parts) != name:
                found.add(".".join(parts))
    return found


#: ``"package.module:Name"``: an entry point named in a string
ENTRY_POINT = re.compile(r"^([A-Za-z_]\w*(?:\.[A-Za-z_]\w*)*):[A-Za-z_][\w-]*$")


def entry_point_modules(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The modules of ``modules`` that ``name`` names in entry-point strings (``"pkg.mod:Name"``)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and (m := ENTRY_POINT.match(node.value)):
            if m[1] in modules and m[1] != name:
                found.add(m[1])
    return found


def import_graph() -> dict[str, set[str]]:
    modules = module_files()
    return {name: imported_modules(name, f, modules) for name, f in modules.items()}


def reference_graph() -> dict[str, set[str]]:
    """Imports and entry-point strings: what the layering is checked on."""
    modules = module_files()
    return {name: imported_modules(name, f, modules) | entry_point_modules(name, f, modules)
            for name, f in modules.items()}


def strongly_connected(graph: dict[str, set[str]]) -> list[set[str]]:
    """Tarjan's algorithm: the groups of modules that reach each other (size > 1 only)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    groups: list[set[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                group.add(w)
                if w == v:
                    break
            if len(group) > 1:
                groups.append(group)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return groups


def test_the_import_walker_sees_imports_inside_functions_and_relative_ones():
    modules = module_files()
    # agents.turn_calibration imports the turn measurement at the top, flagellum.cli imports
    # physics.errors inside main(): both must be seen
    assert "agents.turn_measurement" in imported_modules("agents.turn_calibration",
                                                              modules["agents.turn_calibration"], modules)
    assert "physics.errors" in imported_modules("flagellum.cli", modules["flagellum.cli"], modules)


def test_the_cycle_finder_finds_a_cycle():
    assert strongly_connected({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [{"a", "b", "c"}]
    assert strongly_connected({"a": {"b"}, "b": set()}) == []


def test_no_file_imports_itself_round_a_cycle():
    groups = [frozenset(g) for g in strongly_connected(import_graph())]
    unexpected = [sorted(g) for g in groups if g not in KNOWN_CYCLES]
    assert not unexpected, f"import cycles between files: {unexpected}"


@pytest.mark.parametrize("known", sorted(KNOWN_CYCLES, key=sorted), ids=lambda g: "<->".join(sorted(g)))
def test_every_known_cycle_still_exists(known):
    """A known exception that has gone must leave the list (so the list cannot hide a new cycle)."""
    groups = [frozenset(g) for g in strongly_connected(import_graph())]
    assert known in groups, f"{sorted(known)} is no longer a cycle: remove it from KNOWN_CYCLES"


def test_the_entry_point_finder_sees_registered_entry_points():
    modules = module_files()
    found = entry_point_modules("agents.registration", modules["agents.registration"], modules)
    assert found == {"agents.turn_decision_env", "agents.surrogate_turn_env", "agents.surrogate_burst_env",
                     "agents.burst_decision_env"}
    assert "flagellum_env.steer_env" in entry_point_modules("flagellum_env.registration",
                                                            modules["flagellum_env.registration"], modules)


def test_no_package_imports_a_layer_above_it():
    rank = {pkg: i for i, pkg in enumerate(LAYERS)}
    upward = []
    for name, targets in reference_graph().items():
        for t in targets:
            if rank[t.split(".")[0]] > rank[name.split(".")[0]]:
                upward.append(f"{name} -> {t}")
    assert not upward, "imports of a higher layer (order: " + " -> ".join(LAYERS) + "): " + ", ".join(sorted(upward))


def test_nothing_imports_the_command_line_package():
    importers = sorted(f"{name} -> {t}" for name, targets in import_graph().items() if not name.startswith("flagellum.")
                       and name != "flagellum" for t in targets if t.split(".")[0] == "flagellum")
    assert not importers, importers


def test_no_script_imports_the_command_line_package():
    """scripts/ call the library layers; the CLI package ``flagellum`` is imported by nothing but itself (and by
    the tests of the command line)."""
    modules = {**module_files(), "flagellum": ROOT / "flagellum" / "__init__.py"}
    importers = sorted(f"{f.relative_to(ROOT)} -> {t}" for f in sorted((ROOT / "scripts").glob("*.py"))
                       for t in imported_modules(f"scripts.{f.stem}", f, modules) if t.split(".")[0] == "flagellum")
    assert not importers, importers


def test_every_layer_is_packaged():
    """pyproject.toml's package list names every layer, so that an install holds them all."""
    tomllib = pytest.importorskip("tomllib")  # Python 3.11+
    include = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]["find"]["include"]
    assert all(f"{pkg}*" in include for pkg in LAYERS), include
