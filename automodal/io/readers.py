"""Reading any supported input file into an :class:`~automodal.frfdata.FRFData`.

:func:`read_any` picks the reader by the file's suffix:

========================  =====================================================
suffix                    reader
========================  =====================================================
``.h5``, ``.hdf5``        :func:`automodal.io.frf_file.read_frf` (the FRF file)
``.uff``, ``.unv``        :func:`automodal.io.uff.read_uff` (dataset 58)
``.csv``, ``.txt``        :func:`automodal.io.tabular.read_csv`
``.npz``                  :func:`automodal.io.tabular.read_npz`
========================  =====================================================

A file with another suffix is read as an FRF file when it carries the HDF5 signature and is
refused otherwise. The readers are imported only when used, so that pyuff is loaded only for
UFF files.

The module also holds :func:`check_frf_arrays`, the checks that every reader of a foreign
format applies to the arrays it has assembled (the same rules as ``spec/frf-file.md``).
"""

from __future__ import annotations

import importlib
import os
from pathlib import Path

import numpy as np

from automodal.errors import InputError
from automodal.frfdata import FRFData

__all__ = [
    "MAX_TEXT_BYTES",
    "MAX_VALUES",
    "READERS",
    "check_frf_arrays",
    "check_is_file",
    "check_size",
    "read_any",
]

MAX_VALUES = 2**26
"""Most numbers a reader loads from one file's arrays (67 108 864: 1 GiB as complex128,
e.g. 10^6 lines of 64 FRFs). A file that declares more is refused before anything is read,
so that a hostile or mistaken file (a huge dataset that was never written, a zip bomb)
cannot exhaust the memory."""

MAX_TEXT_BYTES = 2**29
"""Largest text file (CSV, UFF) a reader parses: 512 MiB. Parsing text costs several times
the file's size in memory, so a larger text file is refused before it is read."""

READERS: dict[str, tuple[str, str]] = {
    ".h5": ("automodal.io.readers", "read_hdf5"),
    ".hdf5": ("automodal.io.readers", "read_hdf5"),
    ".uff": ("automodal.io.uff", "read_uff"),
    ".unv": ("automodal.io.uff", "read_uff"),
    ".csv": ("automodal.io.tabular", "read_csv"),
    ".txt": ("automodal.io.tabular", "read_csv"),
    ".npz": ("automodal.io.tabular", "read_npz"),
}
"""Suffix (lower case) -> (module, function) of the reader used for it."""


def read_any(path: str | os.PathLike[str]) -> FRFData:
    """Read an FRF file, a UFF/UNV file, a CSV/text table or an NPZ archive.

    Parameters
    ----------
    path : str or path-like
        The input file. The suffix (case-insensitive) chooses the reader, see
        :data:`READERS`; with any other suffix the file is read as an automodal FRF file if
        it starts with the HDF5 signature.

    Returns
    -------
    FRFData
        What the chosen reader returns; ``source`` is ``str(path)``.

    Raises
    ------
    InputError
        If the file is missing or a folder, if its type cannot be told from its suffix or
        content, or if the chosen reader refuses it. The message is one line and names the
        file.
    """
    source = str(path)
    p = Path(path)
    check_is_file(p, source)
    target = READERS.get(p.suffix.lower())
    if target is None:
        if not _has_hdf5_signature(p):
            known = ", ".join(sorted(READERS))
            raise InputError(f"unknown input type (expected a suffix among {known}, "
                             "or an HDF5 FRF file)", source)
        target = READERS[".h5"]
    module, name = target
    reader = getattr(importlib.import_module(module), name)
    return reader(path)


def read_hdf5(path: str | os.PathLike[str]) -> FRFData:
    """Read an automodal HDF5 test: FRFs from ``/frf``, or FRFs made from ``/time``.

    A file with time series and no FRFs is turned into FRFs here
    (:func:`automodal.core.from_time.frfdata_from_time`: H1 with forces, half spectra
    against automatically chosen references without); the choices made (segment length,
    references, windows) are kept in ``attributes["time_analysis"]`` so the report shows
    them, and a window's decay rate in ``attributes["window_decay_per_s"]`` so that the
    pipeline can take it out of the damping.
    """
    if not _time_only(path):
        from automodal.io.frf_file import read_frf

        return read_frf(path)
    from automodal.core.from_time import frfdata_from_time
    from automodal.io.time_file import read_time

    ts = read_time(path)
    try:
        data, info = frfdata_from_time(ts)
    except ValueError as exc:
        raise InputError(str(exc), str(path)) from None
    decay = float(info.get("lag_window_decay_per_s") or info.get("exponential_decay_per_s") or 0.0)
    data.attributes["time_analysis"] = info
    data.attributes["window_decay_per_s"] = decay
    data.source = str(path)
    return data


def _time_only(path: str | os.PathLike[str]) -> bool:
    """Whether an HDF5 file has a ``/time`` group and no ``/frf`` (False when unreadable:
    the FRF reader then gives the error)."""
    import h5py

    try:
        with h5py.File(path, "r") as f:
            return "frf" not in f and isinstance(f.get("time"), h5py.Group)
    except Exception:  # noqa: BLE001 - the FRF reader reports what is wrong
        return False


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


def check_size(n_values: int, what: str, source: str) -> None:
    """Refuse an array (or a file's arrays) of more than :data:`MAX_VALUES` numbers.

    Parameters
    ----------
    n_values : int
        How many numbers would be read.
    what : str
        What holds them, for the message (``"/frf (shape (...))"``).
    source : str
        The file, for the message.

    Raises
    ------
    InputError
        If ``n_values`` exceeds :data:`MAX_VALUES`.
    """
    if n_values > MAX_VALUES:
        raise InputError(f"{what} holds {n_values} values, more than the {MAX_VALUES} a reader "
                         "loads (too large to read safely)", source)


def _has_hdf5_signature(path: Path) -> bool:
    """Whether ``path`` is an HDF5 file, by its signature (False when unreadable)."""
    import h5py

    try:
        return bool(h5py.is_hdf5(path))
    except (OSError, ValueError):
        return False


def check_frf_arrays(
    frequency: np.ndarray, frf: np.ndarray, source: str
) -> tuple[np.ndarray, np.ndarray]:
    """Check the arrays a reader has assembled against the rules of the FRF file.

    Parameters
    ----------
    frequency : array_like, shape (n_freq,)
        Frequency lines in Hz.
    frf : array_like, shape (n_freq, n_outputs, n_inputs)
        The FRFs; must already be complex.
    source : str
        The file they come from, for messages.

    Returns
    -------
    frequency : ndarray of float64
    frf : ndarray of complex128
        The same arrays, converted.

    Raises
    ------
    InputError
        If ``frequency`` is not 1-D, has no line, is not finite, has a negative line or is
        not strictly increasing; if ``frf`` is not complex, not 3-D with one line per
        frequency, has a non-finite value, or has no imaginary part anywhere (real data
        dressed as complex).
    """
    freq = np.asarray(frequency)
    values = np.asarray(frf)
    if freq.ndim != 1 or freq.size == 0:
        raise InputError(f"the frequency axis must be 1-D and not empty, not of shape "
                         f"{freq.shape}", source)
    freq = freq.astype(np.float64)
    if not np.all(np.isfinite(freq)):
        n_bad = int(np.count_nonzero(~np.isfinite(freq)))
        raise InputError(f"the frequency axis has {n_bad} non-finite value(s) (NaN or inf)",
                         source)
    if freq[0] < 0:
        raise InputError(f"the frequency axis has negative values (first line {freq[0]:g} Hz)",
                         source)
    bad = np.flatnonzero(np.diff(freq) <= 0)
    if bad.size:
        k = int(bad[0]) + 1
        raise InputError(f"the frequencies are not strictly increasing (line {k}: "
                         f"{freq[k]:g} Hz after {freq[k - 1]:g} Hz)", source)
    if values.dtype.kind != "c":
        raise InputError(f"the FRFs are real (dtype {values.dtype}); real FRFs are refused, "
                         "not given zero phase", source)
    if values.ndim != 3 or values.shape[0] != freq.size:
        raise InputError(f"the FRF array has shape {values.shape}; expected "
                         f"({freq.size}, n_outputs, n_inputs)", source)
    if values.size == 0:
        raise InputError(f"the FRF array is empty (shape {values.shape})", source)
    values = values.astype(np.complex128)
    n_bad = int(np.count_nonzero(~np.isfinite(values)))
    if n_bad:
        raise InputError(f"the FRFs have {n_bad} non-finite value(s) (NaN or inf)", source)
    if not np.any(values.imag):
        raise InputError("every imaginary part of the FRFs is zero: real-valued data, not "
                         "complex FRFs", source)
    return freq, values
