"""Writing files atomically: a reader sees the old file or the whole new one, never a part."""

from __future__ import annotations

import os
import secrets
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


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
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.with_name(f".{target.name}.{secrets.token_hex(6)}.tmp{target.suffix}")
    try:
        yield tmp
        _fsync_file(tmp)
        os.replace(tmp, target)
    except BaseException:
        _remove_quietly(tmp)
        raise
    _fsync_dir(target.parent)


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
