"""The package's layout, checked statically: no import cycle, and a numerical core without I/O.

Every module of ``automodal`` is parsed with :mod:`ast` (nothing is imported). Its imports,
at module level and inside functions alike, make the edges of the import graph; a
``from package import name`` counts as an import of ``package.name`` when that is a module.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "automodal"

FORBIDDEN_IN_CORE = (
    "h5py", "pyuff", "matplotlib", "click", "automodal.io", "automodal.app", "automodal.cli",
    "automodal.pipeline", "automodal.report_model",
)
"""What no module of ``automodal/core`` may import: file formats, figures, the command line,
the I/O package, the application layer, the pipeline and the report model (the core reads
no report)."""

LAYERS_ABOVE_IO = ("automodal.app", "automodal.cli", "automodal.pipeline")
"""What ``automodal/io`` may not import: it reads and writes files for the layers above."""


def module_name(path: Path) -> str:
    """The dotted name of the module in ``path``."""
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def all_modules() -> dict[str, Path]:
    """Every module of the package, by dotted name."""
    return {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def parse(path: Path) -> ast.Module:
    """The syntax tree of a module."""
    return ast.parse(path.read_text(encoding="utf-8"), filename=str(path))


def _type_checking_only(tree: ast.Module) -> set[int]:
    """Ids of the nodes under ``if TYPE_CHECKING:``: never run, so no edge of the graph."""
    skipped: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skipped.update(id(child) for stmt in node.body for child in ast.walk(stmt))
    return skipped


def imported_names(name: str, path: Path, tree: ast.Module) -> Iterator[tuple[str, int]]:
    """Every (dotted name, line) the module imports at run time, relative imports
    resolved; for ``from X import a`` both ``X`` and ``X.a`` (the caller keeps what is a
    module)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    skipped = _type_checking_only(tree)
    for node in ast.walk(tree):
        if id(node) in skipped:
            continue
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, node.lineno
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            yield base, node.lineno
            for alias in node.names:
                yield f"{base}.{alias.name}", node.lineno


def import_graph() -> dict[str, set[str]]:
    """Module -> the package's modules it imports (anywhere in its code)."""
    modules = all_modules()
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        targets = {target for target, _ in imported_names(name, path, parse(path))}
        graph[name] = {t for t in targets if t in modules and t != name}
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of ``graph`` as a list of nodes (first repeated at the end), or None."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        path.pop()
        state[node] = 2
        return None

    for start in sorted(graph):
        if start not in state:
            found = visit(start)
            if found:
                return found
    return None


def test_find_cycle_finds_a_cycle_and_only_a_cycle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b", "c"}, "b": {"c"}, "c": set()}) is None


def test_the_graph_sees_function_level_and_relative_imports():
    tree = ast.parse("def f():\n    from automodal.io import limits\nfrom . import hdf5\n")
    names = {n for n, _ in imported_names("automodal.io.x", PACKAGE / "io" / "x.py", tree)}
    assert {"automodal.io.limits", "automodal.io.hdf5"} <= names


def test_no_import_cycle_inside_the_package():
    graph = import_graph()
    assert "automodal.io.readers" in graph and "automodal.io.frf_file" in graph
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_io_format_modules_import_only_shared_helpers():
    """The format modules use the shared helpers, never each other or the dispatcher."""
    formats = {"frf_file", "time_file", "tabular", "uff"}
    graph = import_graph()
    for fmt in sorted(formats):
        imported = {m.rpartition(".")[2] for m in graph[f"automodal.io.{fmt}"]
                    if m.startswith("automodal.io.")}
        assert not imported & (formats | {"readers"}), (fmt, imported)


def test_io_imports_no_layer_above_it():
    graph = import_graph()
    found = [(m, t) for m in graph if m.startswith("automodal.io")
             for t in graph[m] if t.startswith(LAYERS_ABOVE_IO)]
    assert not found, found


def test_no_private_name_is_imported_across_io_modules():
    """The modules of ``automodal.io`` share public helpers only (``from automodal.x import
    _name`` is refused there)."""
    found = []
    for name, path in all_modules().items():
        if not name.startswith("automodal.io."):
            continue
        for node in ast.walk(parse(path)):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("automodal"):
                private = [a.name for a in node.names if a.name.startswith("_")
                           and not a.name.startswith("__")]
                if private:
                    found.append(f"{name}:{node.lineno} imports {private} from {node.module}")
    assert not found, found


def core_problems(name: str, path: Path) -> list[str]:
    """Why a core module is not pure: it imports a file format or automodal.io, or opens
    files."""
    tree = parse(path)
    problems = []
    for target, line in imported_names(name, path, tree):
        if any(target == bad or target.startswith(bad + ".") for bad in FORBIDDEN_IN_CORE):
            problems.append(f"{name}:{line} imports {target}")
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            func = node.func
            called = func.id if isinstance(func, ast.Name) else (
                func.attr if isinstance(func, ast.Attribute) else "")
            if called in ("open", "read_text", "write_text", "read_bytes", "write_bytes",
                          "savez", "savez_compressed", "savetxt", "loadtxt", "genfromtxt"):
                problems.append(f"{name}:{node.lineno} calls {called}()")
            elif called in ("load", "save") and isinstance(func, ast.Attribute) and \
                    isinstance(func.value, ast.Name) and func.value.id in ("np", "numpy"):
                problems.append(f"{name}:{node.lineno} calls np.{called}()")
    return problems


def test_core_problems_are_seen():
    source = "import h5py\ndef f(p):\n    from automodal.io import hdf5\n    open(p)\n"
    path = PACKAGE / "core" / "x.py"
    tree = ast.parse(source)
    problems = [t for t, _ in imported_names("automodal.core.x", path, tree)]
    assert "h5py" in problems and "automodal.io.hdf5" in problems


@pytest.mark.parametrize("name", sorted(n for n in all_modules()
                                        if n.startswith("automodal.core")))
def test_core_does_no_input_or_output(name):
    """``automodal/core`` is pure: arrays in, arrays out (no h5py, pyuff, automodal.io,
    no file opened)."""
    assert core_problems(name, all_modules()[name]) == []


def readme_layout_paths() -> set[str]:
    """The ``automodal/...`` paths named in the first column of the README's layout table."""
    text = (PACKAGE.parent / "README.md").read_text(encoding="utf-8")
    section = text.split("## Layout", 1)[1].split("\n## ", 1)[0]
    paths = set()
    for row in section.splitlines():
        if row.startswith("| `automodal"):
            first = row.split("|")[1]
            paths.update(p for p in first.replace("`", " ").replace(",", " ").split()
                         if p.startswith("automodal"))
    return paths


def test_readme_layout_matches_the_tree():
    """Every path the README's layout table names exists, and every module of the package
    (each file of ``core``, ``io`` and the top level; the ``app`` and ``cli`` packages) is
    in the table."""
    named = readme_layout_paths()
    root = PACKAGE.parent
    missing = sorted(p for p in named if not (root / p.rstrip("/")).exists())
    assert not missing, f"README names paths that do not exist: {missing}"
    covered = {p.rstrip("/") for p in named}
    unlisted = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(root).as_posix()
        if path.name in ("__main__.py",) or "/cli/" in rel:
            continue
        if path.name == "__init__.py" and rel != "automodal/__init__.py":
            continue
        if rel not in covered and path.parent.relative_to(root).as_posix() not in covered:
            unlisted.append(rel)
    assert not unlisted, f"modules missing from the README's layout table: {unlisted}"
