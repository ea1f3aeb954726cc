"""Files of ``automodal design``: the expected modes it reads and the lines it writes.

Expected modes come from

* an automodal report (``.json``, ``.h5``/``.hdf5``): its physical modes;
* a modes file of ``automodal simulate`` (JSON, ``"format": "automodal-modes"``);
* a CSV table with a header row naming the columns ``frequency_hz`` and ``damping_ratio``
  (other columns are ignored), one mode per row.

The lines are written as CSV (one column ``frequency_hz``, one line per row) or JSON
(``"format": "automodal-lines"``, see ``docs/cli.md``), atomically.
"""

from __future__ import annotations

import csv
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from automodal import __version__
from automodal.core.line_design import LineDesign
from automodal.errors import InputError
from automodal.io.atomic import atomic_path
from automodal.io.json_safe import json_safe

FORMAT = "automodal-lines"
VERSION = 1
SUFFIXES = (".csv", ".json")
"""Suffixes of the files :func:`write_design` writes."""

MODES_CSV_COLUMNS = ("frequency_hz", "damping_ratio")
MAX_CSV_BYTES = 16 << 20
"""Largest CSV of expected modes read (16 MiB: far more modes than any test has)."""


def design_suffix(path: str | os.PathLike[str]) -> str:
    """The output's kind from its suffix (``.csv`` or ``.json``); refused otherwise."""
    suffix = Path(path).suffix.lower()
    if suffix not in SUFFIXES:
        raise InputError(f"cannot write lines as {suffix or 'a file without a suffix'!r}:"
                         " give a .csv or .json file", os.fspath(path))
    return suffix


def read_expected_modes(path: str | os.PathLike[str]) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies (Hz) and damping ratios of the expected modes in ``path``.

    Raises
    ------
    InputError
        The file is missing or unreadable, holds no mode, or a mode lacks a finite
        frequency or damping ratio (the message names the file).
    """
    p = Path(path)
    if not p.is_file():
        raise InputError("no such file", os.fspath(path))
    if p.suffix.lower() == ".csv":
        f, z = _read_csv(p)
    elif _is_modes_json(p):
        from automodal.io.modes_file import read_modes_json

        modes = read_modes_json(p)
        f, z = np.asarray(modes.frequency_hz, float), np.asarray(modes.damping_ratio, float)
    else:
        from automodal.io.report import load_report

        report = load_report(p)
        phys = report.physical_modes
        f = np.array([m.frequency_hz for m in phys], dtype=float)
        z = np.array([np.nan if m.damping_ratio is None else m.damping_ratio for m in phys],
                     dtype=float)
        if not phys:
            raise InputError("the report has no physical mode to design for", os.fspath(p))
    bad = np.flatnonzero(~(np.isfinite(f) & np.isfinite(z)))
    if bad.size:
        raise InputError(f"mode {bad[0] + 1} has no finite frequency and damping ratio;"
                         " give the modes with --mode F:ZETA instead", os.fspath(p))
    if f.size == 0:
        raise InputError("no expected mode in the file", os.fspath(p))
    return f, z


def _is_modes_json(path: Path) -> bool:
    """Whether ``path`` is a JSON file of ``automodal simulate``'s modes (not a report)."""
    if path.suffix.lower() != ".json":
        return False
    try:
        with path.open("rb") as fh:
            head = fh.read(4096).decode("utf-8", errors="replace")
    except OSError:
        return False
    return '"automodal-modes"' in head


def _read_csv(path: Path) -> tuple[np.ndarray, np.ndarray]:
    if path.stat().st_size > MAX_CSV_BYTES:
        raise InputError(f"a CSV of expected modes over {MAX_CSV_BYTES >> 20} MiB is not read",
                         os.fspath(path))
    try:
        with path.open(newline="", encoding="utf-8-sig") as fh:
            rows = list(csv.reader(fh))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"not a readable CSV file ({exc})", os.fspath(path)) from None
    rows = [r for r in rows if any(c.strip() for c in r)]
    if not rows:
        raise InputError("empty CSV file", os.fspath(path))
    header = [c.strip().lower() for c in rows[0]]
    missing = [c for c in MODES_CSV_COLUMNS if c not in header]
    if missing:
        raise InputError(f"the header row must name the columns {', '.join(MODES_CSV_COLUMNS)}"
                         f" (missing: {', '.join(missing)})", os.fspath(path))
    cols = [header.index(c) for c in MODES_CSV_COLUMNS]
    values = []
    for number, row in enumerate(rows[1:], start=2):
        try:
            values.append([float(row[i]) for i in cols])
        except (IndexError, ValueError):
            raise InputError(f"row {number}: frequency_hz and damping_ratio must be numbers",
                             os.fspath(path)) from None
    a = np.array(values, dtype=float).reshape(-1, 2)
    return a[:, 0], a[:, 1]


def design_dict(design: LineDesign, band_hz: tuple[float, float]) -> dict[str, Any]:
    """The JSON content of a design."""
    modes = [
        {"frequency_hz": float(f), "damping_ratio": float(z), "half_power_lines": int(c),
         "guaranteed_lines": int(g)}
        for f, z, c, g in zip(design.mode_frequency_hz, design.mode_damping_ratio,
                              design.half_power_lines, design.guaranteed_lines, strict=True)
    ]
    return {
        "format": FORMAT, "version": VERSION, "automodal_version": __version__,
        "rule": design.rule, "band_hz": [float(band_hz[0]), float(band_hz[1])],
        "n_lines": int(design.frequency_hz.size),
        "bilinear_scale_s": float(design.bilinear_scale),
        "expected_modes": modes,
        "frequency_hz": [float(x) for x in design.frequency_hz],
    }


def write_design(path: str | os.PathLike[str], design: LineDesign,
                 band_hz: tuple[float, float]) -> None:
    """Write the lines to ``path`` (``.csv`` or ``.json``), atomically."""
    suffix = design_suffix(path)
    with atomic_path(path) as tmp:
        if suffix == ".json":
            text = json.dumps(json_safe(design_dict(design, band_hz)), indent=1)
            tmp.write_text(text + "\n", encoding="utf-8")
        else:
            with tmp.open("w", newline="", encoding="utf-8") as fh:
                fh.write("frequency_hz\n")
                for x in design.frequency_hz:
                    fh.write(f"{_exact(x)}\n")


def _exact(x: float) -> str:
    """``x`` with enough digits to be read back exactly."""
    return repr(float(x)) if math.isfinite(x) else "nan"
