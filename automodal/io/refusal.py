"""The refusal wrapper shared by the readers: every problem becomes one InputError line.

A reader's inner function takes ``(path, source)`` and raises :class:`Refused` (a problem
with the file, without its name), :class:`~automodal.errors.InputError` (already naming the
file), or lets a library error escape (h5py, numpy, zipfile, pyuff). :func:`read_refusing`
refuses a path that is not a file, runs it, and turns the first and the last into an
:class:`~automodal.errors.InputError` that names the file, in one line, never a traceback.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from automodal.errors import InputError
from automodal.io.limits import check_is_file

__all__ = ["READ_ERRORS", "Refused", "describe", "read_refusing"]

READ_ERRORS = (OSError, RuntimeError, KeyError, ValueError, TypeError)
"""Exceptions of the libraries a reader uses that mean "this file cannot be read"."""

_T = TypeVar("_T")


class Refused(Exception):
    """A problem with the file being read; :func:`read_refusing` adds the path.

    Parameters
    ----------
    problem : str
        What is wrong, in one line.
    """

    def __init__(self, problem: str) -> None:
        super().__init__(problem)
        self.problem = problem


def read_refusing(read: Callable[[Path, str], _T], path: str | os.PathLike[str]) -> _T:
    """Refuse a path that is not a file, then run ``read(Path(path), str(path))``, turning
    every refusal or read failure into one :class:`~automodal.errors.InputError` naming the
    file.

    Parameters
    ----------
    read : callable
        The reader's inner function, ``read(path, source)``; ``path`` is an existing file.
    path : str or path-like
        The file.

    Returns
    -------
    What ``read`` returns.

    Raises
    ------
    InputError
        For a missing path or a folder (:func:`~automodal.io.limits.check_is_file`), a
        :class:`Refused` problem, an :class:`InputError` raised by ``read`` (as it
        is, with the file's name added when it names no file), or one of
        :data:`READ_ERRORS` (``"cannot read the file: ..."``).
    """
    source = str(path)
    p = Path(path)
    try:
        check_is_file(p, source)
        return read(p, source)
    except Refused as exc:
        raise InputError(exc.problem, source) from None
    except InputError as exc:
        if exc.path is None:  # a shared helper's refusal, which does not know the file
            raise InputError(exc.problem, source) from None
        raise
    except READ_ERRORS as exc:
        raise InputError(f"cannot read the file: {describe(exc)}", source) from exc


def describe(exc: BaseException) -> str:
    """One line saying what an unexpected exception was (its text, else its type).

    Parameters
    ----------
    exc : BaseException

    Returns
    -------
    str
    """
    return " ".join(str(exc).split()) or type(exc).__name__
