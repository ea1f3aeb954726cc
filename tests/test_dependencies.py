"""The package's imports agree with ``pyproject.toml``.

Every module under ``automodal/`` is parsed with :mod:`ast` (imports at module level and
inside functions). Each third-party top-level name is mapped to its distribution, and:

* every distribution imported at run time is declared in ``[project].dependencies``, or,
  when it is only imported lazily inside a function under a ``try`` that catches
  ``ImportError`` (an optional feature), in the optional extra that the guard names
  (``pip install 'automodal[dask]'``) or, if it names none, in some extra;
* every declared runtime dependency is imported somewhere.

Imports under ``if TYPE_CHECKING:`` are not run and do not count. Known disagreements are
listed in :data:`KNOWN_GAPS`; remove an entry when ``pyproject.toml`` is fixed (the test
:func:`test_known_gaps_are_still_gaps` fails until then, so the list cannot go stale).
"""

from __future__ import annotations

import ast
import importlib.metadata
import re
import sys
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import pytest

tomllib = pytest.importorskip("tomllib")  # Python >= 3.11

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "automodal"
FIRST_PARTY = "automodal"

MODULE_TO_DISTRIBUTION = {
    "skfuzzy": "scikit-fuzzy",
    "sklearn": "scikit-learn",
    "yaml": "PyYAML",
    "PIL": "Pillow",
    "mpl_toolkits": "matplotlib",
    "dateutil": "python-dateutil",
}
"""Import names whose distribution has another name (checked before the installed
metadata, so the answer does not depend on what happens to be installed)."""

KNOWN_GAPS: frozenset[tuple[str, str]] = frozenset()
"""Disagreements tolerated for now, as ``(kind, distribution)``; none today."""


# ---------------------------------------------------------------------------------------
# The scanner
# ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ImportSite:
    """One imported top-level name and where it is imported."""

    module: str
    where: str
    lazy: bool  # inside a function
    guarded: bool  # inside a ``try`` whose handlers catch ImportError
    extra: str | None  # the extra that the guard's message names
    type_checking: bool  # under ``if TYPE_CHECKING:``


_IMPORT_ERRORS = {"ImportError", "ModuleNotFoundError"}
"""Handlers that guard an optional import (a broad ``except Exception`` around a reader's
call guards its errors, not its import)."""
_EXTRA_IN_MESSAGE = re.compile(re.escape(FIRST_PARTY) + r"\[([A-Za-z0-9_.-]+)\]")


def _catches_import_error(handler: ast.ExceptHandler) -> bool:
    if handler.type is None:
        return False
    types = handler.type.elts if isinstance(handler.type, ast.Tuple) else [handler.type]
    names = {t.id if isinstance(t, ast.Name) else getattr(t, "attr", "") for t in types}
    return bool(names & _IMPORT_ERRORS)


def _named_extra(handlers: list[ast.ExceptHandler]) -> str | None:
    for h in handlers:
        for node in ast.walk(h):
            if isinstance(node, ast.Constant) and isinstance(node.value, str):
                found = _EXTRA_IN_MESSAGE.search(node.value)
                if found:
                    return found.group(1)
    return None


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


class _Scanner(ast.NodeVisitor):
    def __init__(self, where: str) -> None:
        self.where = where
        self.sites: list[ImportSite] = []
        self._depth = 0
        self._guards: list[str | None] = []  # extra named by each enclosing guard
        self._type_checking = 0

    def _add(self, module: str) -> None:
        self.sites.append(
            ImportSite(
                module=module.split(".")[0],
                where=self.where,
                lazy=self._depth > 0,
                guarded=bool(self._guards),
                extra=next((e for e in reversed(self._guards) if e), None),
                type_checking=self._type_checking > 0,
            )
        )

    def visit_Import(self, node: ast.Import) -> None:
        for alias in node.names:
            self._add(alias.name)

    def visit_ImportFrom(self, node: ast.ImportFrom) -> None:
        if node.level == 0 and node.module:  # relative imports are first-party
            self._add(node.module)

    def _function(self, node: ast.AST) -> None:
        self._depth += 1
        self.generic_visit(node)
        self._depth -= 1

    visit_FunctionDef = visit_AsyncFunctionDef = visit_Lambda = _function

    def visit_Try(self, node: ast.Try) -> None:
        guarded = any(_catches_import_error(h) for h in node.handlers)
        if guarded:
            self._guards.append(_named_extra(node.handlers))
        for stmt in node.body:
            self.visit(stmt)
        if guarded:
            self._guards.pop()
        for part in (node.handlers, node.orelse, node.finalbody):
            for stmt in part:
                self.visit(stmt)

    visit_TryStar = visit_Try

    def visit_If(self, node: ast.If) -> None:
        if _is_type_checking(node.test):
            self._type_checking += 1
            for stmt in node.body:
                self.visit(stmt)
            self._type_checking -= 1
            for stmt in node.orelse:
                self.visit(stmt)
        else:
            self.generic_visit(node)


def scan_source(source: str, where: str = "<string>") -> list[ImportSite]:
    """Import sites of one module's source."""
    scanner = _Scanner(where)
    scanner.visit(ast.parse(source, filename=where))
    return scanner.sites


def scan_package(package: Path = PACKAGE) -> list[ImportSite]:
    """Import sites of every module of the package."""
    sites: list[ImportSite] = []
    for path in sorted(package.rglob("*.py")):
        sites.extend(scan_source(path.read_text(encoding="utf-8"), str(path.relative_to(ROOT))))
    return sites


def normalise(name: str) -> str:
    """PEP 503 normalised distribution name."""
    return re.sub(r"[-_.]+", "-", name).lower()


@cache
def _installed() -> dict[str, list[str]]:
    return importlib.metadata.packages_distributions()


def distribution_of(module: str) -> str:
    """Distribution that provides a third-party top-level import name."""
    if module in MODULE_TO_DISTRIBUTION:
        return normalise(MODULE_TO_DISTRIBUTION[module])
    installed = _installed().get(module)
    return normalise(installed[0]) if installed else normalise(module)


def is_third_party(module: str) -> bool:
    """Neither the standard library nor the package itself."""
    return module not in (FIRST_PARTY, "__future__") and module not in sys.stdlib_module_names


def requirement_name(requirement: str) -> str:
    match = re.match(r"\s*([A-Za-z0-9][A-Za-z0-9._-]*)", requirement)
    assert match, f"cannot read requirement {requirement!r}"
    return normalise(match.group(1))


def declared() -> tuple[set[str], dict[str, set[str]]]:
    """Runtime dependencies and optional extras of ``pyproject.toml``."""
    with open(ROOT / "pyproject.toml", "rb") as f:
        project = tomllib.load(f)["project"]
    runtime = {requirement_name(r) for r in project.get("dependencies", [])}
    extras = {
        extra: {requirement_name(r) for r in reqs}
        for extra, reqs in project.get("optional-dependencies", {}).items()
    }
    return runtime, extras


@dataclass
class Audit:
    required: dict[str, list[str]]  # distribution -> modules that import it unguarded
    optional: dict[str, set[str | None]]  # distribution -> extras named by its guards
    undeclared: set[str]
    misplaced_optional: dict[str, str]  # distribution -> why
    unused: set[str]


def audit(sites: list[ImportSite], runtime: set[str], extras: dict[str, set[str]]) -> Audit:
    """Compare import sites with the declared dependencies."""
    required: dict[str, list[str]] = {}
    optional: dict[str, set[str | None]] = {}
    for s in sites:
        if s.type_checking or not is_third_party(s.module):
            continue
        dist = distribution_of(s.module)
        if s.lazy and s.guarded:
            optional.setdefault(dist, set()).add(s.extra)
        else:
            required.setdefault(dist, []).append(s.where)
    undeclared = {d for d in required if d not in runtime}
    misplaced: dict[str, str] = {}
    for dist, named in optional.items():
        if dist in required or dist in runtime:
            continue
        for extra in named:
            if extra is None:
                if not any(dist in reqs for reqs in extras.values()):
                    misplaced[dist] = "in no optional extra"
            elif dist not in extras.get(extra, set()):
                misplaced[dist] = f"not in the extra [{extra}] that its guard names"
    unused = runtime - set(required) - set(optional)
    return Audit(required, optional, undeclared, misplaced, unused)


@pytest.fixture(scope="module")
def package_audit() -> Audit:
    runtime, extras = declared()
    return audit(scan_package(), runtime, extras)


# ---------------------------------------------------------------------------------------
# The package against pyproject.toml
# ---------------------------------------------------------------------------------------


def test_every_imported_distribution_is_declared(package_audit):
    known = {d for kind, d in KNOWN_GAPS if kind == "undeclared"}
    missing = {
        d: sorted(set(package_audit.required[d])) for d in package_audit.undeclared - known
    }
    assert not missing, f"imported but not in [project].dependencies: {missing}"


def test_optional_imports_are_in_their_extra(package_audit):
    assert not package_audit.misplaced_optional, package_audit.misplaced_optional


def test_every_declared_dependency_is_imported(package_audit):
    known = {d for kind, d in KNOWN_GAPS if kind == "unused"}
    assert not package_audit.unused - known, (
        f"declared in [project].dependencies but imported nowhere: "
        f"{sorted(package_audit.unused - known)}"
    )


def test_known_gaps_are_still_gaps(package_audit):
    found = {("undeclared", d) for d in package_audit.undeclared} | {
        ("unused", d) for d in package_audit.unused
    }
    fixed = KNOWN_GAPS - found
    assert not fixed, f"fixed in pyproject.toml: remove {sorted(fixed)} from KNOWN_GAPS"


def test_the_scan_sees_the_imports_it_should(package_audit):
    # a scanner that found nothing would pass the tests above
    for dist in ("numpy", "scipy", "h5py", "click", "matplotlib", "pyuff", "joblib"):
        assert dist in package_audit.required, dist
    assert "scikit-fuzzy" in package_audit.required  # lazily, in physicalness, unguarded
    assert "pyuff" in package_audit.required  # under `except Exception`: not an import guard
    assert "threadpoolctl" in package_audit.required  # lazily, in pipeline, unguarded
    assert package_audit.optional.get("dask") == {"dask"}  # guarded, names [dask]


# ---------------------------------------------------------------------------------------
# The scanner itself, on hand-made sources
# ---------------------------------------------------------------------------------------

SOURCE = '''
from __future__ import annotations
import os, numpy as np
import scipy.linalg as sla
from . import sibling
from .core import thing
from automodal.core import order
from typing import TYPE_CHECKING
if TYPE_CHECKING:
    from matplotlib.figure import Figure
else:
    import click

def f():
    import skfuzzy
    try:
        from dask.distributed import Client
    except ImportError:
        raise RuntimeError("needs pip install 'automodal[dask]'") from None
    try:
        import yaml
    except ValueError:
        pass

try:
    import h5py
except (OSError, ModuleNotFoundError):
    h5py = None

try:
    import joblib
except Exception:
    pass

class C:
    def method(self):
        import pyuff
'''


def _by_module(sites: list[ImportSite]) -> dict[str, ImportSite]:
    return {s.module: s for s in sites}


def test_scanner_top_level_names_and_relative_imports():
    got = _by_module(scan_source(SOURCE))
    assert set(got) == {
        "__future__", "os", "numpy", "scipy", "automodal", "typing", "matplotlib", "click",
        "skfuzzy", "dask", "yaml", "h5py", "joblib", "pyuff",
    }  # the relative imports are not there
    assert not got["numpy"].lazy and not got["scipy"].guarded


def test_scanner_lazy_guarded_and_type_checking():
    got = _by_module(scan_source(SOURCE))
    assert got["matplotlib"].type_checking and not got["click"].type_checking
    assert got["skfuzzy"].lazy and not got["skfuzzy"].guarded
    assert got["dask"].lazy and got["dask"].guarded and got["dask"].extra == "dask"
    assert got["yaml"].lazy and not got["yaml"].guarded  # ValueError does not guard
    assert not got["h5py"].lazy and got["h5py"].guarded and got["h5py"].extra is None
    assert not got["joblib"].guarded  # `except Exception` is not an import guard
    assert got["pyuff"].lazy  # a method is a function too


def test_distribution_names():
    assert distribution_of("skfuzzy") == "scikit-fuzzy"
    assert distribution_of("sklearn") == "scikit-learn"
    assert distribution_of("yaml") == "pyyaml"
    assert distribution_of("numpy") == "numpy"
    assert requirement_name("dask[distributed]>=2024.1") == "dask"
    assert requirement_name("scikit_fuzzy >= 0.5 ; python_version >= '3.10'") == "scikit-fuzzy"
    assert not is_third_party("os") and not is_third_party("automodal")
    assert is_third_party("numpy")


def test_audit_rules_on_a_hand_made_project():
    sites = scan_source(SOURCE)
    runtime = {"numpy", "scipy", "click", "scikit-fuzzy", "h5py", "joblib", "pyuff", "requests"}
    extras = {"dask": {"dask"}, "test": {"pytest"}}
    a = audit(sites, runtime, extras)
    assert a.undeclared == {"pyyaml"}  # unguarded yaml is required
    assert a.unused == {"requests"}
    assert "matplotlib" not in a.required  # TYPE_CHECKING only
    assert a.misplaced_optional == {}
    a = audit(sites, runtime, {"test": {"dask"}})
    assert a.misplaced_optional == {"dask": "not in the extra [dask] that its guard names"}
