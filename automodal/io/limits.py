"""What every reader refuses before (or right after) reading a file.

The size limits protect the memory from a hostile or mistaken file (a huge dataset that was
never written, a zip bomb, a giant text file): a file that declares too many values, or a
text file too large to parse, is refused before anything is read. The other checks refuse a
path that is not a file, and data of a foreign format that are real numbers dressed as
complex ones. Every refusal is an :class:`~automodal.errors.InputError` of one line naming
the file.

This module imports neither h5py nor pyuff: every reader can use it cheaply.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from automodal.errors import InputError

__all__ = [
    "MAX_TEXT_BYTES",
    "MAX_VALUES",
    "check_is_file",
    "check_not_real_valued",
    "check_size",
    "check_text_size",
    "size_problem",
]

MAX_VALUES = 2**26
"""Most numbers a reader loads from one file's arrays (67 108 864: 1 GiB as complex128,
e.g. 10^6 lines of 64 FRFs). A file that declares more is refused before anything is read,
so that a hostile or mistaken file (a huge dataset that was never written, a zip bomb)
cannot exhaust the memory."""

MAX_TEXT_BYTES = 2**29
"""Largest text file (CSV, UFF) a reader parses: 512 MiB. Parsing text costs several times
the file's size in memory, so a larger text file is refused before it is read."""


def check_is_file(path: Path, source: str) -> None:
    """Refuse a missing path or a folder.

    Parameters
    ----------
    path : Path
        The input.
    source : str
        How to name it in messages.

    Raises
    ------
    InputError
        ``"no such file"`` or ``"is a folder, not an input file"``.
    """
    if not path.exists():
        raise InputError("no such file", source)
    if path.is_dir():
        raise InputError("is a folder, not an input file", source)


def check_text_size(path: Path, source: str) -> None:
    """Refuse a text file larger than :data:`MAX_TEXT_BYTES`, before it is read.

    Parameters
    ----------
    path : Path
        The file (it exists).
    source : str
        How to name it in messages.

    Raises
    ------
    InputError
        If the file is larger than :data:`MAX_TEXT_BYTES`.
    """
    size = path.stat().st_size
    if size > MAX_TEXT_BYTES:
        raise InputError(f"the file has {size} bytes, more than the {MAX_TEXT_BYTES} a text "
                         "reader parses (too large to read safely)", source)


def size_problem(n_values: int, what: str) -> str | None:
    """Why an array (or a file's arrays) of ``n_values`` numbers is too large to read, or
    None when it is not (at most :data:`MAX_VALUES`).

    Parameters
    ----------
    n_values : int
        How many numbers would be read.
    what : str
        What holds them, for the message (``"/frf (shape (...))"``).

    Returns
    -------
    str or None
    """
    if n_values <= MAX_VALUES:
        return None
    return (f"{what} holds {n_values} values, more than the {MAX_VALUES} a reader loads "
            "(too large to read safely)")


def check_size(n_values: int, what: str, source: str) -> None:
    """Refuse an array (or a file's arrays) of more than :data:`MAX_VALUES` numbers.

    Parameters
    ----------
    n_values : int
        How many numbers would be read.
    what : str
        What holds them, for the message.
    source : str
        The file, for the message.

    Raises
    ------
    InputError
        If ``n_values`` exceeds :data:`MAX_VALUES`.
    """
    problem = size_problem(n_values, what)
    if problem:
        raise InputError(problem, source)


def check_not_real_valued(frf: np.ndarray, source: str) -> None:
    """Refuse FRFs of a foreign format whose imaginary parts are all zero.

    A table or a universal file of real numbers in complex columns is real data (magnitudes,
    a real part alone) dressed as complex FRFs; it is refused rather than given zero phase.
    The automodal FRF file stores a complex dtype and needs no such guess.

    Parameters
    ----------
    frf : ndarray, complex
        The FRFs a reader has assembled.
    source : str
        The file, for the message.

    Raises
    ------
    InputError
        If ``frf`` is complex with no non-zero imaginary part.
    """
    if frf.dtype.kind == "c" and not np.any(frf.imag):
        raise InputError("every imaginary part of the FRFs is zero: real-valued data, not "
                         "complex FRFs", source)
