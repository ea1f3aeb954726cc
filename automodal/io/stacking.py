"""One test from several files of FRFs: one file per excitation point (roving hammer) or per
response point (roving sensor), as acquisition software such as SignalCalc exports them."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from automodal.errors import InputError
from automodal.frfdata import FRFData

__all__ = ["STACK_AXES", "stack_frfs", "stem_of"]

STACK_AXES = ("inputs", "outputs")
"""How files combine: as the test's inputs (one file per hammer point) or its outputs (one
file per sensor position)."""


def stem_of(path: str | os.PathLike[str]) -> str:
    """A file's name without its suffixes (``Hxysv00001.txt.gz`` -> ``Hxysv00001``)."""
    name = Path(path).name
    return name.split(".", 1)[0] if not name.startswith(".") else name


def stack_frfs(parts: Sequence[FRFData], along: str) -> FRFData:
    """The FRFs of several files as one test, side by side along ``along``.

    Parameters
    ----------
    parts : sequence of FRFData
        The files' FRFs, in the order their channels take (at least one). They must share
        the frequency lines (to 1e-9 relative) and the quantity, and the number of channels
        on the other axis.
    along : {"inputs", "outputs"}
        ``"inputs"``: each file's inputs become further inputs (one file per hammer point);
        ``"outputs"``: each file's outputs become further outputs.

    Returns
    -------
    FRFData
        Channels named by the file (its name without suffixes; ``name/channel`` for a file
        of several), the first file's other channel names and attributes, the files named in
        ``attributes["stacked_files"]``; coherence when every file has it; no records, nodes
        or coordinates (give them with a geometry file).

    Raises
    ------
    InputError
        For an unknown ``along``, no file, different frequency lines, quantities or channel
        counts; the message names the file that differs.
    """
    if along not in STACK_AXES:
        raise InputError(f"unknown stacking {along!r}; expected one of {', '.join(STACK_AXES)}")
    if not parts:
        raise InputError("no file to stack")
    first = parts[0]
    axis = 2 if along == "inputs" else 1
    other = "outputs" if along == "inputs" else "inputs"
    names: list[str] = []
    for part in parts:
        where = part.source or "a file"
        if part.n_freq != first.n_freq or not np.allclose(part.frequency, first.frequency,
                                                          rtol=1e-9, atol=0.0):
            raise InputError(f"its frequency lines differ from those of {first.source} "
                             "(files stacked into one test must share them)", where)
        if part.quantity != first.quantity:
            raise InputError(f"its quantity is {part.quantity}, that of {first.source} is "
                             f"{first.quantity}", where)
        if part.frf.shape[3 - axis] != first.frf.shape[3 - axis]:
            raise InputError(f"it has {part.frf.shape[3 - axis]} {other}, {first.source} has "
                             f"{first.frf.shape[3 - axis]} (stacking along the {along} needs "
                             f"the same {other})", where)
        stem = stem_of(where)
        own = part.input_names if along == "inputs" else part.output_names
        count = part.frf.shape[axis]
        names += [stem] if count == 1 else [f"{stem}/{own[k]}" for k in range(count)]
    frf = np.concatenate([p.frf for p in parts], axis=axis)
    coherence = (np.concatenate([p.coherence for p in parts], axis=axis)
                 if all(p.coherence is not None for p in parts) else None)
    attributes = dict(first.attributes)
    attributes["stacked_files"] = ", ".join(stem_of(p.source or "?") for p in parts)
    attributes["stacked_along"] = along
    return FRFData(
        frequency=first.frequency, frf=frf, quantity=first.quantity, coherence=coherence,
        output_names=names if along == "outputs" else list(first.output_names),
        input_names=names if along == "inputs" else list(first.input_names),
        attributes=attributes, source=first.source,
    )
