"""The one conversion of automodal's outputs to plain, finite JSON values.

Every writer of JSON content (the report, its ``monitoring`` block, the batch summary) runs
its content through :func:`json_safe`: numpy scalars and arrays become Python ``int``,
``float``, ``bool`` and lists, complex numbers ``{"real": ..., "imag": ...}``, paths and bytes
text, and a NaN or an infinity becomes ``None`` (JSON ``null``) while the field's path is
recorded, so that the writer can add a warning naming it (:func:`non_finite_warnings`).

No I/O here, and only numpy is imported.
"""

from __future__ import annotations

import math
import os
import re
from typing import Any

import numpy as np

__all__ = ["json_safe", "json_safe_with_warnings", "non_finite_warnings"]


def json_safe(value: Any, where: str = "", non_finite: list[str] | None = None) -> Any:
    """A copy of ``value`` made of plain JSON types; non-finite numbers become ``None``.

    Parameters
    ----------
    value : any
        Dicts, lists, tuples, arrays, numpy or Python scalars, strings, bytes, paths;
        anything else becomes its ``str``.
    where : str
        The path of ``value`` in the document (``modes[2].mode_shape.real``), used for the
        paths recorded in ``non_finite``.
    non_finite : list of str, optional
        Receives the path of every NaN or infinity replaced by ``None`` (list elements as
        ``field[i]``).

    Returns
    -------
    any
        ``None``, ``bool``, ``int``, ``float`` (finite), ``str``, ``list`` or ``dict`` with
        ``str`` keys.
    """
    found = [] if non_finite is None else non_finite
    if value is None:
        return None
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, str):
        return str(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        x = float(value)
        if math.isfinite(x):
            return x
        found.append(where)
        return None
    if isinstance(value, (complex, np.complexfloating)):
        return {
            "real": json_safe(value.real, f"{where}.real", found),
            "imag": json_safe(value.imag, f"{where}.imag", found),
        }
    if isinstance(value, dict):
        return {
            str(k): json_safe(v, f"{where}.{k}" if where else str(k), found)
            for k, v in value.items()
        }
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        return [json_safe(v, f"{where}[{i}]", found) for i, v in enumerate(value)]
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if isinstance(value, np.generic):
        return json_safe(value.item(), where, found)
    return str(value)


def non_finite_warnings(paths: list[str], what: str = "report") -> list[str]:
    """One warning per field that had non-finite numbers (list elements counted together).

    Parameters
    ----------
    paths : list of str
        What :func:`json_safe` recorded.
    what : str
        The document, first word of each warning.

    Returns
    -------
    list of str
        ``"<what> field <field>: <n> value(s) not finite, written as null"``. The words
        ``NaN`` and ``Infinity`` are avoided so that a scan of the JSON text finds none.
    """
    counts: dict[str, int] = {}
    for p in paths:
        field = re.sub(r"\[\d+\]$", "", p)
        counts[field] = counts.get(field, 0) + 1
    return [f"{what} field {field}: {n} value(s) not finite, written as null"
            for field, n in counts.items()]


def json_safe_with_warnings(
    value: Any, where: str = "", what: str = "report"
) -> tuple[Any, list[str]]:
    """:func:`json_safe` and the warnings of :func:`non_finite_warnings` in one call."""
    found: list[str] = []
    clean = json_safe(value, where, found)
    return clean, non_finite_warnings(found, what)
