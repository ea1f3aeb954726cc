"""A checker of the automodal report, version 1 (shared/spec/report.md), for the tests.

:func:`validate_report` checks every key the spec requires and its type; it raises
``AssertionError`` naming the first field that is wrong. :func:`assert_no_non_finite_text`
scans JSON text for NaN and infinities, :func:`assert_plain_json_types` checks that a dict
holds only builtin JSON types (no numpy scalars).
"""

from __future__ import annotations

import json
import math
import re
from datetime import datetime
from typing import Any

QUANTITIES = ("displacement", "velocity", "acceleration")
_CREATED = re.compile(r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ$")
_SHA256 = re.compile(r"^[0-9a-f]{64}$")
_MODE_KEYS = (
    "id",
    "frequency_hz",
    "frequency_std_hz",
    "frequency_ci95_hz",
    "damping_ratio",
    "damping_std",
    "damping_ci95",
    "physicalness",
    "physical",
    "n_members",
    "mode_shape",
    "mode_shape_std",
    "mpc",
)


def validate_report(report: Any, nullable: bool = False) -> None:
    """Check a report dict against spec/report.md (version 1).

    Parameters
    ----------
    report : any
        What ``report_dict`` or ``read_report`` gave.
    nullable : bool
        Accept ``None`` where a mode's number is expected (a NaN written as null).
    """
    _expect(isinstance(report, dict), "report", "is not an object")
    _keys(report, "report", ("format", "version", "automodal_version", "created", "input",
                             "settings", "modes", "trashbox", "summary", "warnings"))
    _expect(report["format"] == "automodal-report", "format", "is not 'automodal-report'")
    _expect(_is_int(report["version"]) and report["version"] == 1, "version", "is not 1")
    _expect(isinstance(report["automodal_version"], str), "automodal_version", "not a string")
    created = report["created"]
    _expect(isinstance(created, str) and bool(_CREATED.match(created)), "created",
            f"{created!r} is not UTC ISO 8601 with seconds and Z")
    datetime.strptime(created, "%Y-%m-%dT%H:%M:%SZ")
    _expect(isinstance(report["settings"], dict), "settings", "is not an object")
    _expect(_is_int(report["settings"].get("seed")), "settings.seed", "is not an integer")
    n_outputs = _validate_input(report["input"])
    threshold = report["settings"].get("min_physicalness", 0.5)
    _validate_modes(report["modes"], n_outputs, threshold, nullable)
    _keys(report["trashbox"], "trashbox", ("n_members",))
    _expect(_is_count(report["trashbox"]["n_members"]), "trashbox.n_members", "not a count")
    _validate_summary(report)
    warnings = report["warnings"]
    _expect(isinstance(warnings, list) and all(isinstance(w, str) for w in warnings),
            "warnings", "is not a list of strings")


def assert_no_non_finite_text(text: str) -> None:
    """JSON text holds no NaN, Infinity or -Infinity, as a token or anywhere else."""

    def refuse(token: str) -> None:
        raise AssertionError(f"JSON text holds {token}")

    json.loads(text, parse_constant=refuse)
    for word in ("NaN", "Infinity"):
        assert word not in text, f"JSON text contains {word!r}"


def assert_plain_json_types(value: Any, where: str = "report") -> None:
    """Only dict, list, str, int, float, bool and None, with finite floats."""
    kind = type(value)
    if kind is dict:
        for k, v in value.items():
            assert type(k) is str, f"{where}: key {k!r} is not a str"
            assert_plain_json_types(v, f"{where}.{k}")
    elif kind is list:
        for i, v in enumerate(value):
            assert_plain_json_types(v, f"{where}[{i}]")
    elif kind is float:
        assert math.isfinite(value), f"{where} is {value}"
    else:
        assert value is None or kind in (str, int, bool), f"{where} has type {kind.__name__}"


# ----------------------------------------------------------------------------- pieces


def _expect(ok: bool, where: str, problem: str) -> None:
    if not ok:
        raise AssertionError(f"{where}: {problem}")


def _keys(obj: Any, where: str, keys: tuple[str, ...]) -> None:
    _expect(isinstance(obj, dict), where, "is not an object")
    missing = [k for k in keys if k not in obj]
    _expect(not missing, where, f"misses {missing}")


def _is_int(x: Any) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def _is_count(x: Any) -> bool:
    return _is_int(x) and x >= 0


def _is_number(x: Any) -> bool:
    return (isinstance(x, (int, float)) and not isinstance(x, bool)) and math.isfinite(x)


def _number(x: Any, where: str, nullable: bool) -> None:
    _expect(_is_number(x) or (nullable and x is None), where, f"{x!r} is not a finite number")


def _numbers(x: Any, where: str, length: int, nullable: bool) -> None:
    _expect(isinstance(x, list) and len(x) == length, where, f"is not a list of {length}")
    for i, v in enumerate(x):
        _number(v, f"{where}[{i}]", nullable)


def _validate_input(inp: Any) -> int:
    keys = ("path", "sha256", "n_freq", "n_outputs", "n_inputs", "band_hz", "quantity",
            "output_names", "input_names", "attributes")
    _keys(inp, "input", keys)
    _expect(inp["path"] is None or isinstance(inp["path"], str), "input.path", "not a string")
    sha = inp["sha256"]
    _expect(sha is None or (isinstance(sha, str) and bool(_SHA256.match(sha))),
            "input.sha256", f"{sha!r} is not a hex SHA-256")
    for key in ("n_freq", "n_outputs", "n_inputs"):
        _expect(_is_int(inp[key]) and inp[key] > 0, f"input.{key}", "not a positive integer")
    _numbers(inp["band_hz"], "input.band_hz", 2, False)
    _expect(0 <= inp["band_hz"][0] < inp["band_hz"][1], "input.band_hz", "is not lo < hi")
    _expect(inp["quantity"] in QUANTITIES, "input.quantity", f"{inp['quantity']!r} unknown")
    for key, n in (("output_names", inp["n_outputs"]), ("input_names", inp["n_inputs"])):
        names = inp[key]
        _expect(isinstance(names, list) and len(names) == n
                and all(isinstance(s, str) for s in names), f"input.{key}",
                f"is not a list of {n} strings")
    _expect(isinstance(inp["attributes"], dict), "input.attributes", "is not an object")
    return int(inp["n_outputs"])


def _validate_modes(modes: Any, n_outputs: int, threshold: float, nullable: bool) -> None:
    _expect(isinstance(modes, list), "modes", "is not a list")
    for i, m in enumerate(modes):
        where = f"modes[{i}]"
        _keys(m, where, _MODE_KEYS)
        _expect(_is_int(m["id"]), f"{where}.id", "is not an integer")
        for key in ("frequency_hz", "frequency_std_hz", "damping_ratio", "damping_std",
                    "physicalness", "mpc"):
            _number(m[key], f"{where}.{key}", nullable)
        for key in ("frequency_ci95_hz", "damping_ci95"):
            _numbers(m[key], f"{where}.{key}", 2, nullable)
            lo, hi = m[key]
            if lo is not None and hi is not None:
                _expect(lo <= hi, f"{where}.{key}", "low end above the high end")
        p = m["physicalness"]
        _expect(isinstance(m["physical"], bool), f"{where}.physical", "is not a boolean")
        if p is not None:
            _expect(0.0 <= p <= 1.0, f"{where}.physicalness", "outside [0, 1]")
            _expect(m["physical"] == (p >= threshold), f"{where}.physical",
                    f"does not match physicalness {p} >= {threshold}")
        _expect(_is_int(m["n_members"]) and m["n_members"] >= 1, f"{where}.n_members",
                "is not a positive integer")
        if m["mpc"] is not None:
            _expect(-1e-9 <= m["mpc"] <= 1 + 1e-9, f"{where}.mpc", "outside [0, 1]")
        _validate_shape(m, where, n_outputs, nullable)
    ids = [m["id"] for m in modes]
    _expect(len(set(ids)) == len(ids), "modes", "ids are not unique")
    freqs = [m["frequency_hz"] for m in modes if m["frequency_hz"] is not None]
    _expect(freqs == sorted(freqs), "modes", "are not sorted by frequency")


def _validate_shape(mode: dict, where: str, n_outputs: int, nullable: bool) -> None:
    shape = mode["mode_shape"]
    _keys(shape, f"{where}.mode_shape", ("real", "imag"))
    _numbers(shape["real"], f"{where}.mode_shape.real", n_outputs, nullable)
    _numbers(shape["imag"], f"{where}.mode_shape.imag", n_outputs, nullable)
    _numbers(mode["mode_shape_std"], f"{where}.mode_shape_std", n_outputs, nullable)
    _expect(all(s is None or s >= 0 for s in mode["mode_shape_std"]),
            f"{where}.mode_shape_std", "has a negative spread")
    entries = [complex(r, i) for r, i in zip(shape["real"], shape["imag"])
               if r is not None and i is not None]
    if entries:
        largest = max(abs(z) for z in entries)
        _expect(largest <= 1 + 1e-12, f"{where}.mode_shape", f"has |entry| {largest} > 1")
        _expect(complex(1, 0) in entries, f"{where}.mode_shape", "has no entry 1 + 0j")


def _validate_summary(report: dict) -> None:
    summary = report["summary"]
    _keys(summary, "summary", ("n_physical", "n_clusters", "n_bootstrap", "runtime_s"))
    for key in ("n_physical", "n_clusters", "n_bootstrap"):
        _expect(_is_count(summary[key]), f"summary.{key}", "is not a count")
    _number(summary["runtime_s"], "summary.runtime_s", False)
    _expect(summary["runtime_s"] >= 0, "summary.runtime_s", "is negative")
    n_physical = sum(1 for m in report["modes"] if m["physical"])
    _expect(summary["n_physical"] == n_physical, "summary.n_physical",
            f"{summary['n_physical']} but {n_physical} modes are physical")
    _expect(summary["n_clusters"] >= n_physical, "summary.n_clusters", "below n_physical")
    _expect(summary["n_bootstrap"] == report["settings"].get("n_bootstrap"),
            "summary.n_bootstrap", "differs from settings.n_bootstrap")
