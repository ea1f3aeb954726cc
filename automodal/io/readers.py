"""Reading any supported input file: the suffix dispatch, in a child process with a time limit.

:func:`read_any` picks the reader by the file's suffix:

========================  =====================================================
suffix                    reader
========================  =====================================================
``.h5``, ``.hdf5``        :func:`read_hdf5`: :func:`automodal.io.frf_file.read_frf`
                          (FRFs) or :func:`automodal.io.time_file.read_time`
                          (a file with time series only)
``.uff``, ``.unv``        :func:`automodal.io.uff.read_uff` (dataset 58: FRFs, or
                          time responses)
``.csv``, ``.tsv``,       :func:`automodal.io.tabular.read_table` (FRFs or samples,
``.txt``                  as the header says)
``.npz``                  :func:`automodal.io.numpy_files.read_npz_any` (FRFs or
                          samples, as the keys say)
``.npy``                  :func:`automodal.io.numpy_files.read_npy` (samples)
``.mat``                  :func:`automodal.io.matlab.read_mat` (samples; MATLAB v5
                          to v7.3)
``.tdms``                 :func:`automodal.io.tdms.read_tdms` (samples; needs the
                          extra ``automodal[tdms]``)
========================  =====================================================

A file with another suffix is read as an HDF5 file when it carries the HDF5 signature and is
refused otherwise. The readers are imported only when used, so that pyuff is loaded only for
UFF files and h5py only for HDF5 files. The readers only read: a time-series file gives a
:class:`~automodal.timedata.TimeSeries`, which the pipeline's input stage
(:func:`automodal.core.from_time.as_frfdata`) turns into FRFs. A file of samples that does
not say everything (its sample rate, which channels are forces, the response quantity) is
completed by :class:`~automodal.io.channels.TimeOptions`, the command line's
``--sample-rate``, ``--forces`` and ``--quantity``
(:func:`automodal.io.channels.to_time_series`); options given for a file of FRFs are
refused.

On Linux the reading runs in a forked child process with a time limit
(:data:`READ_TIMEOUT_S`): a damaged HDF5 file can make the HDF5 library loop for ever (found
by the property-based tests: a corrupted variable-length string attribute, read with the
interpreter lock held) or crash, and neither may hang or kill a batch. Both end in an
:class:`InputError` like any refused file. Elsewhere, and in daemonic processes (which may
not start children), the reading runs in the calling process, without that protection.
:func:`start_reading` lets the caller work while the child reads (a run imports its
analysis meanwhile) and wait for the data later; :func:`read_any` waits at once.

This module imports the format modules (when used); they never import it.
"""

from __future__ import annotations

import importlib
import multiprocessing
import os
import sys
import time
import weakref
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from automodal.errors import InputError
from automodal.io.limits import check_is_file

if TYPE_CHECKING:  # annotations only: the readers import what they return
    from automodal.frfdata import FRFData
    from automodal.io.channels import Channels, TimeOptions
    from automodal.timedata import TimeSeries

__all__ = ["READERS", "READ_TIMEOUT_S", "PendingRead", "read_any", "read_hdf5", "reader_suffix",
           "start_reading"]

READ_TIMEOUT_S = 120.0
"""Longest time one file may take to read, in seconds (the environment variable
``AUTOMODAL_READ_TIMEOUT_S`` overrides it; ``0`` reads in this process, without a limit).
A 2^26-value FRF file (1 GiB) reads in a few seconds."""

READERS: dict[str, tuple[str, str]] = {
    ".h5": ("automodal.io.readers", "read_hdf5"),
    ".hdf5": ("automodal.io.readers", "read_hdf5"),
    ".uff": ("automodal.io.uff", "read_uff"),
    ".unv": ("automodal.io.uff", "read_uff"),
    ".csv": ("automodal.io.tabular", "read_table"),
    ".tsv": ("automodal.io.tabular", "read_table"),
    ".txt": ("automodal.io.tabular", "read_table"),
    ".npz": ("automodal.io.numpy_files", "read_npz_any"),
    ".npy": ("automodal.io.numpy_files", "read_npy"),
    ".mat": ("automodal.io.matlab", "read_mat"),
    ".tdms": ("automodal.io.tdms", "read_tdms"),
    ".csv.gz": ("automodal.io.tabular", "read_table"),
    ".tsv.gz": ("automodal.io.tabular", "read_table"),
    ".txt.gz": ("automodal.io.tabular", "read_table"),
}
"""Suffix (lower case) -> (module, function) of the reader used for it; text tables may be
gzipped (``.txt.gz``), as acquisition software exports are often kept."""


def reader_suffix(path: str | os.PathLike[str]) -> str:
    """The suffix that chooses a file's reader: the last one in lower case, or the last two
    for a gzipped file (``.txt.gz``).

    Parameters
    ----------
    path : str or path-like
        The file's name or path.

    Returns
    -------
    str
        A key of :data:`READERS` when the file has a reader.
    """
    suffixes = [x.lower() for x in Path(path).suffixes]
    if len(suffixes) >= 2 and suffixes[-1] == ".gz":
        return "".join(suffixes[-2:])
    return suffixes[-1] if suffixes else ""

_TAKE_OPTIONS = frozenset({("automodal.io.tabular", "read_table")})
"""Readers that need the options to tell what the file holds (a table's header of channel
names is one of samples only when the sample rate is given)."""


def read_any(path: str | os.PathLike[str],
             options: TimeOptions | None = None) -> FRFData | TimeSeries:
    """Read an FRF file (or its time series), a UFF/UNV file, a CSV/text table, a NumPy,
    MATLAB or TDMS file.

    Parameters
    ----------
    path : str or path-like
        The input file. The suffix (case-insensitive) chooses the reader, see
        :data:`READERS`; with any other suffix the file is read as an automodal FRF file if
        it starts with the HDF5 signature.
    options : TimeOptions, optional
        What the user says about a file of samples: its sample rate, which channels are
        forces, the response quantity (checked against what the file says).

    Returns
    -------
    FRFData or TimeSeries
        What the chosen reader returns (a :class:`TimeSeries` for an HDF5 file with time
        series and no FRFs); ``source`` is ``str(path)``.

    Raises
    ------
    InputError
        If the file is missing or a folder, if its type cannot be told from its suffix or
        content, if the chosen reader refuses it, if ``options`` contradict the file or
        do not complete a file of samples (no sample rate), or are given for a file of
        FRFs. The message is one line and names the file.
    """
    return start_reading(path, options)()


def start_reading(path: str | os.PathLike[str], options: TimeOptions | None = None
                  ) -> PendingRead:
    """Begin :func:`read_any`: calling the returned :class:`PendingRead` waits for the data
    and returns them (or raises what :func:`read_any` raises).

    Where the reading runs in a child process, the caller goes on meanwhile: a command-line
    run imports the analysis's modules while its file is read (the child's own import of
    h5py and the reading took 75-95 ms of a small file's run, in sequence before).
    Elsewhere the reading is done before this returns. A missing file or a folder is
    refused at once.
    """
    check_is_file(Path(path), str(path))
    timeout = _read_timeout()
    if (timeout <= 0 or not sys.platform.startswith("linux")
            or multiprocessing.current_process().daemon):  # a daemon may not have children
        return PendingRead(data=_read_by_suffix(path, options))
    return _read_in_child(path, options, timeout)


class PendingRead:
    """A reading begun by :func:`start_reading`: call it for the data (the first call waits
    for the child and ends it; later calls give the same data or raise the same error), or
    :meth:`cancel` it. A child whose reading is dropped unread is killed when this object
    is collected."""

    def __init__(self, data: FRFData | TimeSeries | None = None,
                 wait: Callable[[], FRFData | TimeSeries] | None = None,
                 cancel: Callable[[], None] | None = None) -> None:
        self._data = data
        self._error: BaseException | None = None
        self._wait = wait
        self._cancel = cancel

    def __call__(self) -> FRFData | TimeSeries:
        if self._wait is not None:
            wait, self._wait = self._wait, None
            try:
                self._data = wait()
            except BaseException as exc:
                self._error = exc
        if self._error is not None:
            raise self._error
        assert self._data is not None
        return self._data

    def cancel(self) -> None:
        """Stop the child (if it still runs) without waiting for its answer."""
        if self._wait is not None and self._cancel is not None:
            self._wait = None
            self._cancel()
            self._error = InputError("the reading was cancelled")


def _read_by_suffix(path: str | os.PathLike[str],
                    options: TimeOptions | None = None) -> FRFData | TimeSeries:
    """Pick the reader by the suffix (or the HDF5 signature), read, and complete a file of
    samples with the options."""
    source = str(path)
    p = Path(path)
    target = READERS.get(reader_suffix(p))
    if target is None:
        from automodal.io.hdf5 import has_hdf5_signature

        if not has_hdf5_signature(p):
            known = ", ".join(sorted(READERS))
            raise InputError(f"unknown input type (expected a suffix among {known}, "
                             "or an HDF5 FRF file)", source)
        target = READERS[".h5"]
    module, name = target
    reader = getattr(importlib.import_module(module), name)
    read = reader(path, options) if target in _TAKE_OPTIONS else reader(path)
    return _completed(read, options, source)


def _completed(read: FRFData | TimeSeries | Channels, options: TimeOptions | None,
               source: str) -> FRFData | TimeSeries:
    """What a reader gave, as FRFs or a time series completed with the options."""
    from automodal.io.channels import Channels, channels_of, to_time_series
    from automodal.timedata import TimeSeries

    given = options.given if options is not None else []
    if isinstance(read, Channels):
        return to_time_series(read, options, source)
    if isinstance(read, TimeSeries):
        return to_time_series(channels_of(read), options, source) if given else read
    if given:
        hint = (" (a table is read as samples when its header names a time column 't' or "
                "'time', or names channels and --sample-rate is given)"
                if READERS.get(reader_suffix(source)) == READERS[".txt"] else "")
        raise InputError(f"{', '.join(given)} describe time series, but the file holds FRFs"
                         f"{hint}", source)
    return read


MAX_READ_TIMEOUT_S = 1e6
"""The longest time limit of a read (11.6 days): the pipe's wait takes milliseconds in a
32-bit integer, which 1e7 s overflowed (exit 1)."""


def _read_timeout() -> float:
    """:data:`READ_TIMEOUT_S`, or the environment's ``AUTOMODAL_READ_TIMEOUT_S``."""
    text = os.environ.get("AUTOMODAL_READ_TIMEOUT_S", "").strip()
    if not text:
        return READ_TIMEOUT_S
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (0 <= value <= MAX_READ_TIMEOUT_S):
        raise InputError(f"AUTOMODAL_READ_TIMEOUT_S={text!r}: give the time limit of a read"
                         f" in seconds, from 0 (no limit) to {MAX_READ_TIMEOUT_S:g}, or unset"
                         " it")
    return value


def _read_in_child(path: str | os.PathLike[str], options: TimeOptions | None,
                   timeout: float) -> PendingRead:
    """:func:`_read_by_suffix` in a forked child that must answer within ``timeout`` (from
    its start), as a :class:`PendingRead`.

    The child sends back the data, or the refusal, or the unexpected exception, which the
    pending read raises as if the reading had happened in this process. A child that does
    not answer in time is killed; one that dies (a crash in a C library) has no answer: both
    are refusals of the file.
    """
    source = str(path)
    context = multiprocessing.get_context("fork")
    receive, send = context.Pipe(duplex=False)
    child = context.Process(target=_child_reads, args=(path, options, send, receive),
                            daemon=True)
    deadline = time.monotonic() + timeout
    child.start()
    send.close()

    owner = os.getpid()

    def end() -> None:
        # also the finalizer of a reading dropped unread; a forked process inherits it,
        # not the child
        if os.getpid() != owner:
            return
        if child.is_alive():
            child.kill()
        child.join()
        receive.close()

    def wait() -> FRFData | TimeSeries:
        try:
            if not receive.poll(max(0.0, deadline - time.monotonic())):
                raise InputError(f"reading did not finish within {timeout:g} s (a damaged "
                                 "file can make the HDF5 library loop)", source)
            try:
                answer = receive.recv()
            except (EOFError, OSError):
                child.join(5.0)
                raise InputError(f"the reader crashed on the file (exit code "
                                 f"{child.exitcode}): a damaged file", source) from None
        finally:
            end()
        kind = answer[0]
        if kind == "data":
            return answer[1]
        if kind == "refused":
            raise InputError(answer[1], answer[2])
        raise answer[1]

    pending = PendingRead(wait=wait, cancel=end)
    weakref.finalize(pending, end)
    return pending


def _child_reads(path: str | os.PathLike[str], options: TimeOptions | None, send: Any,
                 receive: Any) -> None:
    """In the child: read, and send ``("data", FRFData or TimeSeries)``,
    ``("refused", problem, path)`` or ``("error", exception)`` back.

    ``receive``, the parent's end of the pipe, which the fork copied, is closed first: a
    parent killed meanwhile (a cron job's time limit) then leaves the pipe without a reader,
    and the answer's send fails at once, ending the child, rather than waiting forever for
    room in the pipe. (A child caught in an endless read, which the time limit is for, still
    outlives a parent killed meanwhile.)"""
    receive.close()
    answer: tuple[Any, ...]
    try:
        answer = ("data", _read_by_suffix(path, options))
    except InputError as exc:
        answer = ("refused", exc.problem, exc.path)
    except Exception as exc:  # noqa: BLE001 - raised again in the parent
        answer = ("error", exc)
    try:
        send.send(answer)
    except BrokenPipeError:  # the parent is gone: nobody to answer
        pass
    except Exception as exc:  # noqa: BLE001 - an exception that cannot be pickled
        text = " ".join(str(answer[-1]).split())
        try:
            send.send(("error", RuntimeError(f"{type(answer[-1]).__name__}: {text} ({exc})")))
        except BrokenPipeError:
            pass
    finally:
        send.close()


def read_hdf5(path: str | os.PathLike[str]) -> FRFData | TimeSeries:
    """Read an automodal HDF5 test: the FRFs of ``/frf``, or the time series of ``/time``
    when the file has no ``/frf``.

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    FRFData or TimeSeries
        :func:`automodal.io.frf_file.read_frf` or :func:`automodal.io.time_file.read_time`.

    Raises
    ------
    InputError
        What the chosen reader raises.
    """
    if _time_only(path):
        from automodal.io.time_file import read_time

        return read_time(path)
    from automodal.io.frf_file import read_frf

    return read_frf(path)


def _time_only(path: str | os.PathLike[str]) -> bool:
    """Whether an HDF5 file has a ``/time`` group and no ``/frf`` (False when unreadable:
    the FRF reader then gives the error)."""
    import h5py

    try:
        with h5py.File(path, "r") as f:
            return "frf" not in f and isinstance(f.get("time"), h5py.Group)
    except Exception:  # noqa: BLE001 - the FRF reader reports what is wrong
        return False
