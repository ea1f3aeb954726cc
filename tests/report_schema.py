"""A checker of the automodal report, version 1 (docs/report.md), for the tests.

:func:`validate_report` validates a report against the JSON Schema shipped in the package
(``automodal/schemas/report-v1.schema.json``) with ``jsonschema``, then checks what a
schema cannot express (relations between fields: names per channel, the physical decision
against the threshold, the shape normalization, sorted and unique modes, the summary's
counts; and, unless ``nullable``, that no number of a mode is ``null``). It raises
``AssertionError`` naming the first field that is wrong. :func:`assert_no_non_finite_text`
scans JSON text for NaN and infinities, :func:`assert_plain_json_types` checks that a dict
holds only builtin JSON types (no numpy scalars).
"""

from __future__ import annotations

import json
import math
from datetime import datetime
from functools import lru_cache
from typing import Any

import jsonschema

from automodal.schemas import REPORT_V1

_MODE_NUMBERS = ("frequency_hz", "frequency_std_hz", "damping_ratio", "damping_std",
                 "physicalness", "mpc")


@lru_cache(maxsize=1)
def report_validator() -> jsonschema.protocols.Validator:
    """A validator of the package's report schema (the schema itself checked first)."""
    schema = json.loads(REPORT_V1.read_text(encoding="utf-8"))
    cls = jsonschema.validators.validator_for(schema)
    cls.check_schema(schema)
    return cls(schema)


def schema_errors(report: Any) -> list[str]:
    """Every violation of the schema, as ``"<field path>: <message>"``, best first."""
    errors = sorted(report_validator().iter_errors(report), key=jsonschema.exceptions.relevance)
    return [f"{_path(e.absolute_path)}: {e.message}" for e in errors]


def validate_report(report: Any, nullable: bool = False) -> None:
    """Check a report dict against docs/report.md (version 1).

    Parameters
    ----------
    report : any
        What ``report_dict`` or ``read_report`` gave.
    nullable : bool
        Accept ``None`` where a mode's number is expected (a NaN written as null).
    """
    errors = schema_errors(report)
    _expect(not errors, "schema", "; ".join(errors[:3]))
    datetime.strptime(report["created"], "%Y-%m-%dT%H:%M:%SZ")
    _all_finite(report, "report")
    n_outputs = _validate_input(report["input"])
    threshold = report["settings"].get("min_physicalness", 0.5)
    _validate_modes(report["modes"], n_outputs, threshold, nullable)
    _validate_summary(report)


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


def _path(parts: Any) -> str:
    out = "report"
    for p in parts:
        out += f"[{p}]" if isinstance(p, int) else f".{p}"
    return out


def _expect(ok: bool, where: str, problem: str) -> None:
    if not ok:
        raise AssertionError(f"{where}: {problem}")


def _all_finite(value: Any, where: str) -> None:
    """No NaN or infinity anywhere (JSON has none; a schema cannot refuse a Python one)."""
    if isinstance(value, dict):
        for k, v in value.items():
            _all_finite(v, f"{where}.{k}")
    elif isinstance(value, list):
        for i, v in enumerate(value):
            _all_finite(v, f"{where}[{i}]")
    elif isinstance(value, float):
        _expect(math.isfinite(value), where, f"{value!r} is not a finite number")


def _validate_input(inp: dict) -> int:
    """What the schema cannot say of ``input``: the band's order, a name per channel."""
    _expect(inp["band_hz"][0] < inp["band_hz"][1], "input.band_hz", "is not lo < hi")
    for key, n in (("output_names", inp["n_outputs"]), ("input_names", inp["n_inputs"])):
        _expect(len(inp[key]) == n, f"input.{key}", f"is not a list of {n} strings")
    return int(inp["n_outputs"])


def _validate_modes(modes: list, n_outputs: int, threshold: float, nullable: bool) -> None:
    for i, m in enumerate(modes):
        where = f"modes[{i}]"
        if not nullable:
            for key in _MODE_NUMBERS:
                _expect(m[key] is not None, f"{where}.{key}", "is null")
            for key in ("frequency_ci95_hz", "damping_ci95"):
                _expect(None not in m[key], f"{where}.{key}", "holds null")
        for key in ("frequency_ci95_hz", "damping_ci95"):
            lo, hi = m[key]
            if lo is not None and hi is not None:
                _expect(lo <= hi, f"{where}.{key}", "low end above the high end")
        p = m["physicalness"]
        if p is not None:
            # a physical mode below the threshold: a companion the likelihood-ratio test
            # promoted (always refined), its cluster's physicalness left as it was
            _expect(m["physical"] == (p >= threshold) or (
                m["physical"] and m.get("estimator") == "ml"), f"{where}.physical",
                f"does not match physicalness {p} >= {threshold}")
        _validate_shape(m, where, n_outputs, nullable)
    ids = [m["id"] for m in modes]
    _expect(len(set(ids)) == len(ids), "modes", "ids are not unique")
    freqs = [m["frequency_hz"] for m in modes if m["frequency_hz"] is not None]
    _expect(freqs == sorted(freqs), "modes", "are not sorted by frequency")


def _validate_shape(mode: dict, where: str, n_outputs: int, nullable: bool) -> None:
    shape = mode["mode_shape"]
    for key, values in (("mode_shape.real", shape["real"]), ("mode_shape.imag", shape["imag"]),
                        ("mode_shape_std", mode["mode_shape_std"])):
        _expect(len(values) == n_outputs, f"{where}.{key}", f"is not a list of {n_outputs}")
        _expect(nullable or None not in values, f"{where}.{key}", "holds null")
    entries = [complex(r, i) for r, i in zip(shape["real"], shape["imag"])
               if r is not None and i is not None]
    if entries:
        largest = max(abs(z) for z in entries)
        _expect(largest <= 1 + 1e-12, f"{where}.mode_shape", f"has |entry| {largest} > 1")
        _expect(complex(1, 0) in entries, f"{where}.mode_shape", "has no entry 1 + 0j")


def _validate_summary(report: dict) -> None:
    summary = report["summary"]
    _expect(summary["n_bootstrap"] is not None, "summary.n_bootstrap", "is null")
    n_physical = sum(1 for m in report["modes"] if m["physical"])
    _expect(summary["n_physical"] == n_physical, "summary.n_physical",
            f"{summary['n_physical']} but {n_physical} modes are physical")
    _expect(summary["n_clusters"] >= n_physical, "summary.n_clusters", "below n_physical")
    _expect(summary["n_bootstrap"] == report["settings"].get("n_bootstrap"),
            "summary.n_bootstrap", "differs from settings.n_bootstrap")
