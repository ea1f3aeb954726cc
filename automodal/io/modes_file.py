"""The exact modes of a synthetic test, as JSON beside its FRF file.

``automodal simulate out.h5`` writes ``out.modes.json``::

    {
      "format": "automodal-modes", "version": 1, "automodal_version": "0.1.0",
      "n_modes": 6, "n_outputs": 6, "n_inputs": 1,
      "frequency_hz": [...], "damping_ratio": [...],
      "poles": {"real": [...], "imag": [...]},                 # rad/s, Im > 0
      "shapes": {"real": [[...]], "imag": [[...]]},            # n_outputs x n_modes
      "residues": {"real": [[[...]]], "imag": [[[...]]]},      # n_modes x n_out x n_in, optional
      "settings": {...}                                        # how the test was made
    }

Shapes follow the report convention: the largest-magnitude entry of each is ``1 + 0j``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from automodal import __version__
from automodal.core.simulate import Modes
from automodal.core.synthesis import modal_poles
from automodal.errors import InputError
from automodal.io.atomic import atomic_path
from automodal.io.json_safe import json_safe

FORMAT = "automodal-modes"
VERSION = 1


def _complex_json(a: np.ndarray) -> dict[str, Any]:
    a = np.asarray(a, dtype=complex)
    return {"real": a.real.tolist(), "imag": a.imag.tolist()}


def _complex_array(obj: Any, what: str) -> np.ndarray:
    if not isinstance(obj, dict) or "real" not in obj or "imag" not in obj:
        raise ValueError(f"{what} needs 'real' and 'imag'")
    re, im = np.asarray(obj["real"], dtype=float), np.asarray(obj["imag"], dtype=float)
    if re.shape != im.shape:
        raise ValueError(f"{what}: 'real' and 'imag' differ in shape")
    return re + 1j * im


def write_modes_json(
    path: str | os.PathLike, modes: Modes, extra: dict[str, Any] | None = None
) -> None:
    """Write modes and the settings that made them (written whole or not at all).

    Parameters
    ----------
    path : path
        The ``.json`` file to write.
    modes : Modes
    extra : dict, optional
        Settings (system, damping, noise, seed, ...) stored under ``"settings"``.
    """
    path = Path(path)
    doc: dict[str, Any] = {
        "format": FORMAT,
        "version": VERSION,
        "automodal_version": __version__,
        "n_modes": modes.n_modes,
        "n_outputs": modes.n_outputs,
        "frequency_hz": np.asarray(modes.frequency_hz, dtype=float).tolist(),
        "damping_ratio": np.asarray(modes.damping_ratio, dtype=float).tolist(),
        "poles": _complex_json(modes.poles),
        "shapes": _complex_json(modes.shapes),
    }
    if modes.residues is not None:
        doc["n_inputs"] = int(modes.residues.shape[2])
        doc["residues"] = _complex_json(modes.residues)
    doc["settings"] = dict(extra or {})
    non_finite: list[str] = []
    clean = json_safe(doc, "", non_finite)  # numpy scalars/arrays in the settings too
    if non_finite:
        raise ValueError(f"modes file field {non_finite[0]} is not finite")
    text = json.dumps(clean, indent=1, allow_nan=False)
    with atomic_path(path) as tmp:
        tmp.write_text(text + "\n", encoding="utf-8")


def _load(path: Path) -> dict[str, Any]:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError("no such file", path) from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"not a readable JSON file ({exc})", path) from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise InputError(f"not an automodal modes file (format is not {FORMAT!r})", path)
    if not isinstance(doc.get("version"), int) or doc["version"] > VERSION:
        raise InputError(f"modes file version {doc.get('version')!r} is not supported "
                         f"(this reader knows version {VERSION})", path)
    return doc


def read_modes_json(path: str | os.PathLike) -> Modes:
    """Read the modes written by :func:`write_modes_json`.

    Raises
    ------
    InputError
        The file is missing, not JSON, not a modes file, or inconsistent.
    """
    path = Path(path)
    doc = _load(path)
    try:
        n_modes = int(doc["n_modes"])
        if "poles" in doc:
            poles = _complex_array(doc["poles"], "poles").reshape(-1)
        else:
            poles = modal_poles(np.asarray(doc["frequency_hz"], dtype=float),
                                np.asarray(doc["damping_ratio"], dtype=float))
        shapes = _complex_array(doc["shapes"], "shapes").reshape(int(doc["n_outputs"]), n_modes)
        residues = None
        if "residues" in doc:
            residues = _complex_array(doc["residues"], "residues").reshape(
                n_modes, int(doc["n_outputs"]), int(doc["n_inputs"]))
        if poles.size != n_modes:
            raise ValueError(f"{poles.size} poles for {n_modes} modes")
        modes = Modes.from_poles(poles, shapes, residues)
        # keep the stored values themselves (they equal the derived ones to round-off)
        for name in ("frequency_hz", "damping_ratio"):
            stored = np.asarray(doc[name], dtype=float).reshape(-1)
            if stored.size != n_modes:
                raise ValueError(f"{stored.size} values of {name} for {n_modes} modes")
            setattr(modes, name, stored)
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"inconsistent modes file ({exc})", path) from None
    return modes


def read_modes_settings(path: str | os.PathLike) -> dict[str, Any]:
    """The ``"settings"`` of a modes file (how the synthetic test was made)."""
    path = Path(path)
    return dict(_load(path).get("settings", {}))
