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

On Linux the reading runs in a forked child process with a time limit
(:data:`READ_TIMEOUT_S`): a damaged HDF5 file can make the HDF5 library loop for ever (found
by the property-based tests: a corrupted variable-length string attribute, read with the
interpreter lock held) or crash, and neither may hang or kill a batch. Both end in an
:class:`InputError` like any refused file. Elsewhere, and in daemonic processes (which may
not start children), the reading runs in the calling process, without that protection.

The module also holds :func:`check_frf_arrays`, the checks that every reader of a foreign
format applies to the arrays it has assembled (the same rules as ``spec/frf-file.md``).
"""

from __future__ import annotations

import importlib
import multiprocessing
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

from automodal.errors import InputError
from automodal.frfdata import FRFData

__all__ = [
    "MAX_TEXT_BYTES",
    "MAX_VALUES",
    "READERS",
    "READ_TIMEOUT_S",
    "check_frf_arrays",
    "check_is_file",
    "check_size",
    "check_text_size",
    "read_any",
    "size_problem",
]

MAX_VALUES = 2**26
"""Most numbers a reader loads from one file's arrays (67 108 864: 1 GiB as complex128,
e.g. 10^6 lines of 64 FRFs). A file that declares more is refused before anything is read,
so that a hostile or mistaken file (a huge dataset that was never written, a zip bomb)
cannot exhaust the memory."""

READ_TIMEOUT_S = 120.0
"""Longest time one file may take to read, in seconds (the environment variable
``AUTOMODAL_READ_TIMEOUT_S`` overrides it; ``0`` reads in this process, without a limit).
A 2^26-value FRF file (1 GiB) reads in a few seconds."""

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
    check_is_file(Path(path), source)
    timeout = _read_timeout()
    if (timeout <= 0 or not sys.platform.startswith("linux")
            or multiprocessing.current_process().daemon):  # a daemon may not have children
        return _read_by_suffix(path)
    return _read_in_child(path, timeout)


def _read_by_suffix(path: str | os.PathLike[str]) -> FRFData:
    """Pick the reader by the suffix (or the HDF5 signature) and read."""
    source = str(path)
    p = Path(path)
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


def _read_timeout() -> float:
    """:data:`READ_TIMEOUT_S`, or the environment's ``AUTOMODAL_READ_TIMEOUT_S``."""
    text = os.environ.get("AUTOMODAL_READ_TIMEOUT_S", "").strip()
    try:
        return float(text) if text else READ_TIMEOUT_S
    except ValueError:
        return READ_TIMEOUT_S


def _read_in_child(path: str | os.PathLike[str], timeout: float) -> FRFData:
    """:func:`_read_by_suffix` in a forked child that must answer within ``timeout``.

    The child sends back the data, or the refusal, or the unexpected exception, which are
    raised here as if the reading had happened in this process. A child that does not
    answer in time is killed; one that dies (a crash in a C library) has no answer: both
    are refusals of the file.
    """
    source = str(path)
    context = multiprocessing.get_context("fork")
    receive, send = context.Pipe(duplex=False)
    child = context.Process(target=_child_reads, args=(path, send), daemon=True)
    child.start()
    send.close()
    try:
        if not receive.poll(timeout):
            raise InputError(f"reading did not finish within {timeout:g} s (a damaged file "
                             "can make the HDF5 library loop)", source)
        try:
            answer = receive.recv()
        except (EOFError, OSError):
            child.join(5.0)
            raise InputError(f"the reader crashed on the file (exit code {child.exitcode}): "
                             "a damaged file", source) from None
    finally:
        if child.is_alive():
            child.kill()
        child.join()
        receive.close()
    kind = answer[0]
    if kind == "data":
        return answer[1]
    if kind == "refused":
        raise InputError(answer[1], answer[2])
    raise answer[1]


def _child_reads(path: str | os.PathLike[str], send: Any) -> None:
    """In the child: read, and send ``("data", FRFData)``, ``("refused", problem, path)``
    or ``("error", exception)`` back."""
    answer: tuple[Any, ...]
    try:
        answer = ("data", _read_by_suffix(path))
    except InputError as exc:
        answer = ("refused", exc.problem, exc.path)
    except Exception as exc:  # noqa: BLE001 - raised again in the parent
        answer = ("error", exc)
    try:
        send.send(answer)
    except Exception as exc:  # noqa: BLE001 - an exception that cannot be pickled
        text = " ".join(str(answer[-1]).split())
        send.send(("error", RuntimeError(f"{type(answer[-1]).__name__}: {text} ({exc})")))
    finally:
        send.close()


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
