"""Node coordinates from a universal file: datasets 15 and 2411 (nodes), read with pyuff.

Both datasets give, per node, its number, the coordinate system its coordinates are in
(the definition system), the system its displacements are measured in, a colour and
``x, y, z``. Only the global cartesian system is read: system 0, or a system that a
dataset 2420 of the same file defines as cartesian with the identity transformation
(which some exporters number 1). A node in any other system is refused rather than placed
wrongly, since the direction convention of a transformation matrix is not stated in a way
that can be checked. A node given twice (in one dataset or across datasets) is refused.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from automodal.errors import InputError
from automodal.io.limits import check_text_size
from automodal.io.refusal import describe, read_refusing

__all__ = ["GEOMETRY_SETS", "Nodes", "nodes_of_file", "open_uff", "read_uff_nodes"]

GEOMETRY_SETS = (15, 2411)
"""Datasets that give node coordinates."""

Nodes = dict[int, tuple[float, float, float]]
"""Node number -> (x, y, z), as :class:`automodal.io.geometry.Geometry` holds them."""

_SYSTEMS_SET = 2420
"""Dataset of coordinate-system definitions."""

_GLOBAL = 0
"""The global cartesian coordinate system's number."""


def read_uff_nodes(path: str | os.PathLike[str]) -> Nodes:
    """The nodes of a universal file's datasets 15 and 2411 (``--geometry file.uff``).

    Parameters
    ----------
    path : str or path-like
        A ``.uff`` or ``.unv`` file (it may hold other datasets too: they are skipped).

    Returns
    -------
    dict of int to (x, y, z)
        Node coordinates (the channels' nodes come from the FRF file).

    Raises
    ------
    InputError
        One line naming the file: unreadable, larger than the text limit, no dataset 15
        or 2411, a node given twice, a non-integer node number, a non-finite coordinate,
        or a coordinate system other than the global cartesian one.
    """
    def read(p: Path, source: str) -> Nodes:
        check_text_size(p, source)
        uff, types = open_uff(p, source)
        nodes = nodes_of_file(uff, types, source)
        if nodes is None:
            found = sorted({t for t in types if t > 0})
            what = ("data sets of type " + ", ".join(map(str, found))) if found else "none"
            raise InputError("no node coordinates (dataset 15 or 2411) in the file; found "
                             f"{what}", source)
        return nodes

    return read_refusing(read, path)


def open_uff(path: Path, source: str) -> tuple[Any, list[int]]:
    """The file open with pyuff, and the type of each of its datasets.

    Raises
    ------
    InputError
        If pyuff cannot read it (one line naming ``source``).
    """
    if not _ends_with_delimiter(path):
        raise InputError("the file ends inside a data set (its last line is not the '-1' that"
                         " closes one): it is truncated; write it again", source)
    try:
        import pyuff

        uff = pyuff.UFF(os.fspath(path))
        return uff, [int(t) for t in uff.get_set_types()]
    except Exception as exc:  # noqa: BLE001 - pyuff raises bare Exception
        raise InputError(f"cannot read as a UFF file: {describe(exc)}", source) from exc


def _ends_with_delimiter(path: Path) -> bool:
    """Whether a file that opens with a data set's ``-1`` delimiter also ends with one,
    which closes every data set: pyuff dropped a set cut short (a copy interrupted
    mid-file) without a word, and its channels with it."""
    with open(path, "rb") as fh:
        if not fh.read(256).lstrip().startswith(b"-1"):
            return True  # not opened by a delimiter: pyuff says what it is
        fh.seek(0, os.SEEK_END)
        size = fh.tell()
        fh.seek(max(0, size - 256))
        tail = fh.read()
    # a binary set's closing delimiter follows its data on the same line
    return re.search(rb"(^|\s)-1$", tail.rstrip(b" \t\r\n\x00\x1a")) is not None


def nodes_of_file(uff: Any, types: list[int], source: str) -> Nodes | None:
    """The nodes of the datasets 15 and 2411 of an open ``pyuff.UFF``, or None if it has none.

    Parameters
    ----------
    uff : pyuff.UFF
        The file, open.
    types : list of int
        Its dataset types, in order (``uff.get_set_types()``).
    source : str
        The file, for messages.

    Raises
    ------
    InputError
        As :func:`read_uff_nodes`.
    """
    wanted = [i for i, t in enumerate(types) if t in GEOMETRY_SETS]
    if not wanted:
        return None
    identity = _identity_systems(uff, types, source)
    nodes: Nodes = {}
    first: dict[int, int] = {}
    for i in wanted:
        dset = _read_set(uff, i, types[i], source)
        where = f"data set {i + 1} (dataset {types[i]})"
        columns = [np.atleast_1d(np.asarray(dset.get(k, []), dtype=float))
                   for k in ("node_nums", "def_cs", "disp_cs", "x", "y", "z")]
        if len({c.size for c in columns}) != 1:
            raise InputError(f"{where} is damaged: its node columns differ in length", source)
        for number, def_cs, disp_cs, *xyz in zip(*columns):
            node = _node_number(number, where, source)
            for kind, system in (("coordinate", def_cs), ("displacement", disp_cs)):
                if int(system) != _GLOBAL and int(system) not in identity:
                    raise InputError(
                        f"{where}: node {node} has its {kind}s in coordinate system "
                        f"{int(system)}; only the global cartesian system (0) is read: "
                        "export the nodes in global coordinates", source)
            if node in nodes:
                raise InputError(f"node {node} is given twice (data sets {first[node]} and "
                                 f"{i + 1})", source)
            if not np.all(np.isfinite(xyz)):
                raise InputError(f"{where}: node {node} has a non-finite coordinate", source)
            nodes[node] = (float(xyz[0]), float(xyz[1]), float(xyz[2]))
            first[node] = i + 1
    return nodes or None


def _read_set(uff: Any, index: int, kind: int, source: str) -> dict[str, Any]:
    """Dataset ``index`` of the file (0-based), refused in one line if pyuff cannot read it."""
    try:
        return uff.read_sets(index)
    except Exception as exc:  # noqa: BLE001 - pyuff raises bare Exception
        raise InputError(f"cannot read data set {index + 1} (dataset {kind}): "
                         f"{describe(exc)}", source) from exc


def _node_number(value: float, where: str, source: str) -> int:
    """A node number read as a float, as an int (refused unless a whole number)."""
    if not (np.isfinite(value) and value == int(value)):
        raise InputError(f"{where}: node number {value!r} is not an integer", source)
    return int(value)


def _identity_systems(uff: Any, types: list[int], source: str) -> set[int]:
    """Numbers of the coordinate systems that the file's datasets 2420 define as cartesian
    with the identity transformation (the global system under another number)."""
    found: set[int] = set()
    for i, t in enumerate(types):
        if t != _SYSTEMS_SET:
            continue
        dset = _read_set(uff, i, t, source)
        labels = np.atleast_1d(np.asarray(dset.get("CS_sys_labels", []), dtype=float))
        kinds = np.atleast_1d(np.asarray(dset.get("CS_types", []), dtype=float))
        matrices = dset.get("CS_matrices", [])
        for label, kind, matrix in zip(labels, kinds, matrices):
            m = np.asarray(matrix, dtype=float)
            if int(kind) == 0 and m.shape == (4, 3) and np.allclose(
                    m, np.vstack([np.eye(3), np.zeros(3)]), rtol=0, atol=1e-12):
                found.add(int(label))
    return found
