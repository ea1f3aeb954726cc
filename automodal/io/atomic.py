"""Writing files atomically: a reader sees the old file or the whole new one, never a part."""

from __future__ import annotations

import errno
import io
import os
import secrets
import shutil
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import h5py


@contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Give a temporary path to write to, and move it onto ``path`` when the block succeeds.

    The temporary file is in the same folder as ``path`` (so that the final rename is atomic)
    and is named ``.{name}.{random}.tmp{suffix}``: it is hidden, and keeps the suffix of
    ``path`` so that writers which look at the suffix (h5py, JSON, matplotlib) still work.
    The context manager does not create the temporary file; the block must. Missing
    folders above ``path`` are made first (as every command of automodal does for its
    outputs, ``docs/cli.md``).

    On success the temporary file is flushed to disk (``fsync``) and renamed onto ``path``
    with :func:`os.replace`. If the block raises (or the fsync or rename fails), the
    temporary file is deleted, ``path`` is left as it was, and the exception propagates.

    Parameters
    ----------
    path : str or path-like
        The file to write in the end.

    Yields
    ------
    pathlib.Path
        Where to write the new content.

    Examples
    --------
    >>> with atomic_path("report.json") as tmp:  # doctest: +SKIP
    ...     tmp.write_text("{}")
    """
    with atomic_paths([path]) as (tmp,):
        yield tmp


@contextmanager
def atomic_paths(paths: Sequence[str | os.PathLike[str]]) -> Iterator[list[Path]]:
    """:func:`atomic_path` for several files, written all or not at all: each gets its
    temporary path beside it, and only when the block has written every one are they
    flushed and renamed onto ``paths``; if the block raises (a full disk at the second
    report, say), every temporary file is deleted and no path is touched. Yields the
    temporary paths, in the order of ``paths``."""
    targets = [Path(p) for p in paths]
    for target in targets:
        target.parent.mkdir(parents=True, exist_ok=True)
    tmps = [t.with_name(f".{t.name}.{secrets.token_hex(6)}.tmp{t.suffix}") for t in targets]
    try:
        yield tmps
        for tmp in tmps:
            _fsync_file(tmp)
        for tmp, target in zip(tmps, targets):
            os.replace(tmp, target)
    except BaseException:
        for tmp in tmps:
            _remove_quietly(tmp)
        raise
    for folder in {t.parent for t in targets}:
        _fsync_dir(folder)


@contextmanager
def hdf5_in_memory(path: str | os.PathLike[str]) -> Iterator[h5py.File]:
    """An HDF5 file to fill, built in memory and written atomically onto ``path`` when the
    block succeeds (:func:`atomic_path`).

    For reports and histories, small next to the memory a run holds. HDF5 writing into a
    file on a full disk crashed the process (a segmentation fault, the temporary file left
    behind, on a 64 KiB file system); Python's write of the finished image raises
    ``OSError`` (``ENOSPC``) instead, which the commands report in one line.
    """
    import h5py

    buffer = io.BytesIO()
    with h5py.File(buffer, "w") as f:
        yield f
    with atomic_path(path) as tmp:
        tmp.write_bytes(buffer.getbuffer())


def check_free_space(path: str | os.PathLike[str], arrays: Iterable[Any]) -> None:
    """Raise ``OSError`` (``ENOSPC``) when the folder of ``path`` (or the nearest existing
    one above it) has less free than the bytes of ``arrays`` (``None`` entries skipped) and a
    mebibyte: a large HDF5 file is written straight to disk, and HDF5 crashes when the disk
    fills under it."""
    import numpy as np  # not at import: the command line loads no library to start

    n_bytes = sum(np.asarray(a).nbytes for a in arrays if a is not None)
    try:
        free = shutil.disk_usage(nearest_existing_folder(path)).free
    except OSError:
        return
    if free < int(n_bytes) + (1 << 20):
        raise OSError(errno.ENOSPC, f"{os.strerror(errno.ENOSPC)} ({free} bytes free, about"
                      f" {int(n_bytes)} needed)", os.fspath(path))


def nearest_existing_folder(path: str | os.PathLike[str]) -> Path:
    """The folder of ``path``, or the nearest one above it that exists (what would hold the
    folders still to be made; it may be a file where a folder is expected)."""
    folder = Path(os.path.abspath(path)).parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    return folder


def _fsync_file(path: Path) -> None:
    """Flush a closed file's content to disk."""
    flags = os.O_RDWR if os.name == "nt" else os.O_RDONLY
    fd = os.open(path, flags)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_dir(folder: Path) -> None:
    """Flush a folder's entries (the rename) to disk where the platform allows it."""
    if os.name == "nt":
        return
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _remove_quietly(path: Path) -> None:
    """Delete ``path`` if it exists, ignoring errors (used while another error propagates)."""
    try:
        path.unlink(missing_ok=True)
    except OSError:
        pass
