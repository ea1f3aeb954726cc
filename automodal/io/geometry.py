"""Test geometry from a small CSV file (or a universal file's nodes): node coordinates, and
channels on nodes.

The file (``--geometry nodes.csv``) has one or two tables, each starting with its header
row::

    node,x,y,z
    1,0.0,0.0,0.0
    2,0.5,0.0,0.0
    channel,node,direction
    tip,2,+Z

The first gives each node's coordinates; the second (optional) puts channels, named as
in the FRF file, on nodes and directions (``+X``, ``-Y``, ``+Z``, ``+RX``...), for files
that do not say where their channels are. Blank lines and lines starting with ``#`` are
skipped. Anything else is refused with a line that names the row.

A ``.uff`` or ``.unv`` file gives the node table from its datasets 15 and 2411
(:mod:`automodal.io.uff_geometry`); the channels' nodes then come from the FRF file.
"""

from __future__ import annotations

import csv
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from automodal.errors import InputError

if TYPE_CHECKING:
    from automodal.frfdata import FRFData
    from automodal.report_model import Report

__all__ = ["Geometry", "apply_to_data", "apply_to_report", "read_geometry"]

UFF_SUFFIXES = (".uff", ".unv")
"""Suffixes of a geometry file read as a universal file (datasets 15 and 2411)."""

_DIRECTION = re.compile(r"^[+-]?(X|Y|Z|RX|RY|RZ)$")
_MAX_BYTES = 64 << 20


@dataclass
class Geometry:
    """Node coordinates and, optionally, where channels are.

    Attributes
    ----------
    nodes : dict of int to (x, y, z)
    channels : dict of str to (node, direction)
    source : str or None
        The file, for messages.
    """

    nodes: dict[int, tuple[float, float, float]]
    channels: dict[str, tuple[int, str]] = field(default_factory=dict)
    source: str | None = None

    def locate(
        self, names: list[str], nodes: list[int] | None, directions: list[str] | None
    ) -> tuple[list[int], list[str], list[list[float]]]:
        """Nodes, directions and coordinates of the channels ``names``: the channel table
        first, else the ``nodes`` and ``directions`` given (from the FRF file).

        Raises
        ------
        InputError
            If a channel has no node, or its node no coordinates.
        """
        out_nodes, out_dirs, xyz = [], [], []
        for k, name in enumerate(names):
            if name in self.channels:
                node, direction = self.channels[name]
            elif nodes is not None:
                node = int(nodes[k])
                direction = directions[k] if directions is not None else "+Z"
            else:
                raise InputError(f"channel {name!r} has no node: add a row"
                                 f" '{name},NODE,DIRECTION' under 'channel,node,direction'",
                                 self.source)
            if node not in self.nodes:
                raise InputError(f"node {node} of channel {name!r} has no coordinates",
                                 self.source)
            out_nodes.append(node)
            out_dirs.append(direction)
            xyz.append(list(self.nodes[node]))
        return out_nodes, out_dirs, xyz


def read_geometry(path: str | os.PathLike[str]) -> Geometry:
    """Read a geometry file: CSV (see the module text), or UFF/UNV nodes (by the suffix).

    Raises
    ------
    InputError
        If the file is missing or too large, has no node table, a row of the wrong
        length, a non-numeric value, a node or channel twice, or an unknown direction;
        for a UFF file, what :func:`automodal.io.uff_geometry.read_uff_nodes` refuses.
    """
    source = os.fspath(path)
    if Path(source).suffix.lower() in UFF_SUFFIXES:
        from automodal.io.uff_geometry import read_uff_nodes

        return Geometry(nodes=read_uff_nodes(path), source=source)
    try:
        if os.path.getsize(path) > _MAX_BYTES:
            raise InputError("the geometry file is larger than 64 MiB", source)
        with open(path, newline="", encoding="utf-8-sig") as fh:
            rows = list(csv.reader(fh))
    except (OSError, UnicodeDecodeError) as exc:
        reason = getattr(exc, "strerror", None) or type(exc).__name__
        raise InputError(f"cannot read the geometry file: {reason}", source) from None
    nodes: dict[int, tuple[float, float, float]] = {}
    channels: dict[str, tuple[int, str]] = {}
    table = None
    for number, raw in enumerate(rows, start=1):
        row = [c.strip() for c in raw]
        if not any(row) or row[0].startswith("#"):
            continue
        head = [c.lower() for c in row]
        if head == ["node", "x", "y", "z"] or head == ["channel", "node", "direction"]:
            table = head[0]
            continue
        where = f"row {number}"
        if table is None:
            raise InputError(f"{where}: expected the header 'node,x,y,z' first", source)
        if table == "node":
            node, *xyz = _fields(row, 4, where, source)
            key = _integer(node, where, source)
            if key in nodes:
                raise InputError(f"{where}: node {key} is given twice", source)
            nodes[key] = tuple(_number(v, where, source) for v in xyz)  # type: ignore[assignment]
        else:
            name, node, direction = _fields(row, 3, where, source)
            if name in channels:
                raise InputError(f"{where}: channel {name!r} is given twice", source)
            if not _DIRECTION.match(direction.upper()):
                raise InputError(f"{where}: direction {direction!r} is not one of +X, -Y,"
                                 " +Z, +RX ...", source)
            text = direction.upper()
            channels[name] = (_integer(node, where, source),
                              text if text[0] in "+-" else "+" + text)
    if not nodes:
        raise InputError("no node table ('node,x,y,z' and one row per node)", source)
    return Geometry(nodes=nodes, channels=channels, source=source)


def apply_to_report(report: Report, geometry: Geometry) -> None:
    """Set the report's ``input.mode_shape_nodes``, ``mode_shape_directions`` and
    ``mode_shape_xyz`` from ``geometry`` (in place).

    Raises
    ------
    InputError
        As :meth:`Geometry.locate`.
    """
    inp = report.input
    nodes, directions, xyz = geometry.locate(
        report.shape_channels, inp.mode_shape_nodes, inp.mode_shape_directions)
    inp.mode_shape_nodes, inp.mode_shape_directions, inp.mode_shape_xyz = nodes, directions, xyz


def apply_to_data(data: FRFData, geometry: Geometry) -> FRFData:
    """``data`` with its outputs' nodes, directions and coordinates from ``geometry``, and
    its inputs' nodes and directions where the channel table names them all.

    Raises
    ------
    InputError
        As :meth:`Geometry.locate`, for the outputs.
    """
    from dataclasses import replace

    nodes, directions, xyz = geometry.locate(
        list(data.output_names),
        None if data.output_nodes is None else [int(n) for n in data.output_nodes],
        data.output_directions)
    changes: dict = {"output_nodes": np.array(nodes, dtype=np.int64),
                     "output_directions": directions, "output_xyz": np.array(xyz, float)}
    if all(name in geometry.channels for name in data.input_names):
        located = [geometry.channels[name] for name in data.input_names]
        changes["input_nodes"] = np.array([n for n, _ in located], dtype=np.int64)
        changes["input_directions"] = [d for _, d in located]
    return replace(data, **changes)


def _fields(row: list[str], n: int, where: str, source: str) -> list[str]:
    if len(row) != n:
        raise InputError(f"{where}: {len(row)} fields, expected {n}", source)
    return row


def _integer(text: str, where: str, source: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise InputError(f"{where}: node {text!r} is not an integer", source) from None


def _number(text: str, where: str, source: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not np.isfinite(value):
        raise InputError(f"{where}: coordinate {text!r} is not a finite number", source)
    return value
