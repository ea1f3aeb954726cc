"""Exceptions that the command line turns into exit statuses."""

from __future__ import annotations


class AutomodalError(Exception):
    """Base class of automodal's own errors."""


class InputError(AutomodalError):
    """Bad usage or bad input: the CLI prints one line and exits with status 2.

    Parameters
    ----------
    path : str or None
        The file the problem is in (named first in the message), if any.
    problem : str
        What is wrong, in one line.
    """

    def __init__(self, problem: str, path: str | None = None) -> None:
        self.path = None if path is None else str(path)
        self.problem = " ".join(str(problem).split())
        super().__init__(f"{self.path}: {self.problem}" if self.path else self.problem)
