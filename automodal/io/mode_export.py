"""The physical modes of a report as files for FE and animation tools: UFF dataset 55 or CSV.

* UFF (``.uff``, ``.unv``): one dataset 55 ("data at nodes") per physical mode, complex
  eigenvalue (analysis type 3), numbered with the mode's number (``mode_number``: 1, 2, ... by
  frequency, as the tables, figures and monitoring number it), written with pyuff. Each
  shape channel's value goes to its node and direction (``input.mode_shape_nodes`` and
  ``mode_shape_directions`` of the report, or a geometry given with ``--geometry``):
  ``+X`` to the node's first component, ``-Y`` negated to its second, and so on; rotations
  (``+RX``...) to components 4 to 6 (then six values per node). Without known nodes and
  directions, channel ``k`` is node ``k`` (1-based) in ``+Z``. The eigenvalue is
  ``-zeta w + j w sqrt(1 - zeta^2)``.
* CSV (``.csv``): one row per physical mode: ``mode`` (its number, ``mode_number``),
  ``frequency_hz``, ``damping_ratio``, then per channel ``<name>_re`` and ``<name>_im``
  (or ``<name>_mag`` and ``<name>_phase_deg`` with ``polar``), the shape as the report
  holds it (largest entry 1 + 0j).

Files are written atomically (:mod:`automodal.io.atomic`).
"""

from __future__ import annotations

import csv
import os
from pathlib import Path

import numpy as np

from automodal.core.synthesis import modal_poles
from automodal.errors import InputError
from automodal.io.atomic import atomic_path
from automodal.report_model import Report, ReportMode

__all__ = ["EXPORT_SUFFIXES", "export_modes", "export_suffix", "shape_dofs", "write_modes_csv",
           "write_modes_uff"]

EXPORT_SUFFIXES = (".uff", ".unv", ".csv")
_AXES = {"X": 0, "Y": 1, "Z": 2, "RX": 3, "RY": 4, "RZ": 5}


def export_suffix(path: str | os.PathLike[str]) -> str:
    """The export type of ``path``: its suffix in lower case, one of :data:`EXPORT_SUFFIXES`.

    Raises
    ------
    InputError
        For another suffix.
    """
    suffix = Path(path).suffix
    if suffix.lower() not in EXPORT_SUFFIXES:
        raise InputError(f"unknown export type {suffix or '(none)'!r}: use .uff, .unv or .csv",
                         os.fspath(path))
    return suffix.lower()


def export_modes(path: str | os.PathLike[str], report: Report, polar: bool = False) -> int:
    """Write the physical modes of ``report`` to ``path``; the suffix chooses the format.

    Returns
    -------
    int
        The number of modes written.

    Raises
    ------
    InputError
        For another suffix, a report without physical modes, or channels whose nodes
        and directions collide (nothing is written).
    """
    suffix = export_suffix(path)
    modes = report.physical_modes
    if not modes:
        raise InputError("the report has no physical mode to export", os.fspath(path))
    if suffix == ".csv":
        write_modes_csv(path, report, polar)
    else:
        write_modes_uff(path, report)
    return len(modes)


def shape_dofs(report: Report) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Node, component (0-5: X, Y, Z, RX, RY, RZ) and sign of every shape channel.

    Raises
    ------
    InputError
        If two channels fall on the same node and component, or a direction is none of
        ``[+-](X|Y|Z|RX|RY|RZ)``.
    """
    n = len(report.shape_channels)
    inp = report.input
    nodes = inp.mode_shape_nodes if inp.mode_shape_nodes is not None else range(1, n + 1)
    directions = (inp.mode_shape_directions if inp.mode_shape_directions is not None
                  else ["+Z"] * n)
    component = np.empty(n, dtype=int)
    sign = np.ones(n)
    for k, d in enumerate(directions):
        text = str(d).strip().upper()
        axis = _AXES.get(text.lstrip("+-"))
        if axis is None:
            raise InputError(f"channel {report.shape_channels[k]!r} has direction {d!r}, not"
                             " one of +X, -Y, +RZ ...: give the directions with --geometry")
        component[k] = axis
        sign[k] = -1.0 if text.startswith("-") else 1.0
    node = np.asarray(list(nodes), dtype=int)
    seen: dict[tuple[int, int], str] = {}
    for k, key in enumerate(zip(node.tolist(), component.tolist())):
        if key in seen:
            raise InputError(f"channels {seen[key]!r} and {report.shape_channels[k]!r} are"
                             " both node {} direction {}".format(
                                 key[0], list(_AXES)[key[1]]))
        seen[key] = report.shape_channels[k]
    return node, component, sign


def write_modes_uff(path: str | os.PathLike[str], report: Report) -> None:
    """One UFF dataset 55 per physical mode (see the module text)."""
    import pyuff

    node, component, sign = shape_dofs(report)
    nodes = np.unique(node)
    row = np.searchsorted(nodes, node)
    per_node = 6 if component.max(initial=0) > 2 else 3
    sets = []
    for mode in report.physical_modes:
        values = np.zeros((per_node, nodes.size), dtype=complex)
        values[component, row] = sign * np.nan_to_num(mode.shape, nan=0.0)
        eig = complex(modal_poles(float(mode.frequency_hz), float(mode.damping_ratio or 0.0)))
        sets.append(pyuff.prepare_55(
            model_type=1, id1="automodal identified mode", id2=_mode_line(mode),
            id3=f"report {report.input.path or ''}"[:80], id4="NONE", id5="NONE",
            analysis_type=3, data_ch=2 if per_node == 3 else 3, spec_data_type=8,
            data_type=5, n_data_per_node=per_node,
            **{f"r{i + 1}": values[i] for i in range(per_node)},
            load_case=1, mode_n=_number(mode), eig=eig, modal_a=0j, modal_b=0j,
            node_nums=nodes,
        ))
    with atomic_path(path) as tmp:
        pyuff.UFF(os.fspath(tmp)).write_sets(sets, mode="overwrite")


def write_modes_csv(path: str | os.PathLike[str], report: Report, polar: bool = False) -> None:
    """One row per physical mode (see the module text)."""
    names = report.shape_channels
    parts = ("_mag", "_phase_deg") if polar else ("_re", "_im")
    header = ["mode", "frequency_hz", "damping_ratio"] + [
        f"{name}{part}" for name in names for part in parts]
    with atomic_path(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(header)
        for mode in report.physical_modes:
            shape = mode.shape
            pairs = (np.column_stack([np.abs(shape), np.degrees(np.angle(shape))]) if polar
                     else np.column_stack([shape.real, shape.imag]))
            writer.writerow([_number(mode), repr(float(mode.frequency_hz)),
                             repr(float(mode.damping_ratio or np.nan))]
                            + [repr(float(x)) for x in pairs.ravel()])


def _number(mode: ReportMode) -> int:
    """The mode's number (1, 2, ... by frequency among the physical modes); its id in a
    report whose modes are not numbered."""
    return int(mode.mode_number if mode.mode_number is not None else mode.id)


def _mode_line(mode: ReportMode) -> str:
    """``f 12.345 Hz, zeta 1.23 %`` for a dataset's ID line."""
    zeta = mode.damping_ratio
    damping = "" if zeta is None else f", zeta {100 * zeta:.4g} %"
    return f"f {mode.frequency_hz:.6g} Hz{damping}"
