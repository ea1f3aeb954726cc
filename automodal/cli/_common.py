"""Helpers shared by the CLI commands: turning errors into exit statuses."""

from __future__ import annotations

import errno
import os
import sys
import traceback
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import click

from automodal.cli._startup import defer_unused_numpy_modules
from automodal.errors import InputError
from automodal.io.atomic import nearest_existing_folder

if TYPE_CHECKING:
    from automodal.tracking import Thresholds

EXIT_OK = 0
EXIT_INTERNAL = 1
EXIT_INPUT = 2
EXIT_MONITORING = 3

REPORT_SUFFIXES = (".json", ".h5", ".hdf5")
"""Suffixes of report files (JSON or HDF5), as :mod:`automodal.io.report` writes them."""


@contextmanager
def exit_on_error(debug: bool = False) -> Iterator[None]:
    """Turn exceptions into one line on stderr and the exit statuses of ``docs/cli.md``.

    :class:`InputError` exits 2; any other exception exits 1. With ``debug`` the traceback
    is printed too. Every command's body runs inside it, after click has handled ``--help``,
    so it is also where numpy's submodules that no command uses are made to load on first
    use (:mod:`automodal.cli._startup`), before the body's first import of scipy.
    """
    defer_unused_numpy_modules()
    try:
        yield
    except InputError as exc:
        if debug:
            traceback.print_exc()
        click.echo(f"automodal: error: {exc}", err=True)
        sys.exit(EXIT_INPUT)
    except (click.exceptions.Exit, click.exceptions.Abort, click.ClickException, SystemExit):
        raise
    except KeyboardInterrupt:
        click.echo("automodal: interrupted", err=True)
        sys.exit(130)
    except OSError as exc:
        if exc.errno not in _WRITE_REFUSALS:
            _internal(exc, debug)
        if debug:
            traceback.print_exc()
        where = f"{exc.filename}: " if exc.filename else ""
        click.echo(f"automodal: error: {where}cannot write: {exc.strerror or exc}", err=True)
        sys.exit(EXIT_INPUT)
    except Exception as exc:  # noqa: BLE001 - the CLI boundary
        _internal(exc, debug)


_WRITE_REFUSALS = tuple(getattr(errno, name) for name in ("ENOSPC", "EDQUOT", "EROFS", "EFBIG")
                        if hasattr(errno, name))
"""Errors of a write that the machine, not automodal, caused (a full disk or quota, a
read-only file system, a file too large for it): exit 2 with one line, as for a bad input."""


def _internal(exc: BaseException, debug: bool) -> None:
    """Exit 1 with one line naming the unexpected exception (its traceback with ``debug``)."""
    if debug:
        traceback.print_exc()
    msg = " ".join(str(exc).split()) or type(exc).__name__
    click.echo(f"automodal: internal error: {type(exc).__name__}: {msg}", err=True)
    sys.exit(EXIT_INTERNAL)


def check_output_folder(path: str | os.PathLike[str], what: str) -> None:
    """Refuse, before any work, an output whose folder can be neither found nor made.

    Every command makes the missing folders of its outputs when it writes them (as
    ``mkdir -p`` would); the nearest folder above ``path`` that exists must therefore be a
    folder, and writable.

    Raises
    ------
    InputError
        Naming ``path`` (``what`` says which output it is, e.g. ``"report"``).
    """
    parent = Path(os.path.abspath(path)).parent
    if os.path.isdir(path):
        raise InputError(f"is a folder, where the {what} would be written", os.fspath(path))
    folder = nearest_existing_folder(path)
    if not folder.is_dir():
        raise InputError(f"cannot make the {what}'s folder: {folder} is not a folder",
                         os.fspath(path))
    if not os.access(folder, os.W_OK | os.X_OK):
        problem = (f"the {what}'s folder is not writable" if folder == parent
                   else f"cannot make the {what}'s folder: {folder} is not writable")
        raise InputError(problem, os.fspath(path))


HDF5_SUFFIXES = (".h5", ".hdf5")
"""Suffixes of the HDF5 files the commands write (FRF, time and history files)."""


def check_hdf5_suffix(path: str | os.PathLike[str], what: str) -> None:
    """Refuse an HDF5 output named otherwise (``simulate x.json`` wrote HDF5 under a JSON
    name, which every JSON reader then failed on).

    Raises
    ------
    InputError
        Naming the output and the suffixes allowed.
    """
    if Path(path).suffix.lower() not in HDF5_SUFFIXES:
        raise InputError(f"the {what} is an HDF5 file: name it with the suffix .h5 or .hdf5",
                         os.fspath(path))


def check_outputs_spare_inputs(
    outputs: Iterable[str | os.PathLike[str] | None],
    inputs: Iterable[str | os.PathLike[str] | None],
) -> None:
    """Refuse, before any work, an output that is one of the command's inputs: writing it
    would replace that file (``identify in.h5 -o in.h5`` turned the FRF file into a report).

    Two paths are the same file when they resolve to it (links, ``..``, relative paths);
    ``None`` entries are skipped.

    Raises
    ------
    InputError
        Naming the output and the input it would replace.
    """
    sources = [src for src in inputs if src is not None]
    for out in outputs:
        if out is None:
            continue
        for src in sources:
            if _same_file(out, src):
                raise InputError(f"is also an input ({os.fspath(src)}), which writing it would"
                                 " replace: choose another output", os.fspath(out))


def _same_file(a: str | os.PathLike[str], b: str | os.PathLike[str]) -> bool:
    """Whether ``a`` and ``b`` name the same file (the same resolved path when either does
    not exist yet)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.realpath(a) == os.path.realpath(b)


def debug_option(func: Callable) -> Callable:
    """The ``--debug`` flag: show tracebacks."""
    return click.option("--debug", is_flag=True, help="Show a traceback on errors.")(func)


def test_date_option(func: Callable) -> Callable:
    """``--test-date ISO``: the date of the test, stored as the file's ``test_date``."""
    return click.option(
        "--test-date", "test_date", default=None, metavar="ISO",
        help="Date of the test, ISO 8601 (2024-05-01 or 2024-05-01T10:30:00+02:00);"
             " stored as the attribute test_date, which orders reports in time when"
             " monitoring.")(func)


def checked_test_date(text: str) -> str:
    """``text`` as a UTC ISO 8601 time (``YYYY-MM-DDTHH:MM:SSZ``).

    Raises
    ------
    click.BadParameter
        If it is not an ISO 8601 date or time.
    """
    from automodal.report_model import parse_time

    when = parse_time(text)
    if when is None:
        raise click.BadParameter(f"{text!r} is not an ISO 8601 date or time, such as"
                                 " 2024-05-01 or 2024-05-01T10:30:00Z", param_hint="--test-date")
    return when


class FiniteFloatRange(click.FloatRange):
    """``click.FloatRange`` that also refuses ``nan`` and infinities (a range compares
    ``nan`` as inside, and ``inf`` passes an open upper end)."""

    def convert(self, value, param, ctx):  # type: ignore[no-untyped-def]
        import math

        out = super().convert(value, param, ctx)
        if not math.isfinite(out):
            self.fail(f"{value!r} is not a finite number", param, ctx)
        return out


def _stacked(options: list[Callable], func: Callable) -> Callable:
    """``func`` decorated with ``options``, which show in ``--help`` in the given order."""
    for option in reversed(options):
        func = option(func)
    return func


def threshold_options(func: Callable) -> Callable:
    """The alarm thresholds of a baseline check (:class:`automodal.tracking.Thresholds`),
    ``None`` when not given: ``--shift-sigmas``, ``--min-shift-percent``, ``--min-mac``.
    Their defaults, named in the help, are those of ``Thresholds`` (a test checks)."""
    options = [
        click.option("--shift-sigmas", type=FiniteFloatRange(min=0), default=None, metavar="K",
                     help="Alarm when a frequency moved by more than K combined standard "
                     "deviations of the two runs (and the floor below). Default 5."),
        click.option("--min-shift-percent", type=FiniteFloatRange(0, 100), default=None,
                     metavar="P", help="... and always by more than P % of the baseline "
                     "frequency: raise it for structures that move with temperature. "
                     "Default 0.25."),
        click.option("--min-mac", type=FiniteFloatRange(0, 1), default=None, metavar="MAC",
                     help="Alarm when a mode's shape has a MAC below this with the "
                     "baseline's. Default 0.95."),
    ]
    return _stacked(options, func)


def time_input_options(func: Callable) -> Callable:
    """``--sample-rate``, ``--forces`` and ``--quantity``: what a file of samples does not say
    (``docs/time-input.md``)."""
    from automodal.quantities import QUANTITIES

    options = [
        click.option("--sample-rate", type=float, default=None, metavar="HZ",
                     help="Time input: samples per second, when the file does not carry it "
                     "(refused if it contradicts the file)."),
        click.option("--forces", default=None, metavar="CH,...",
                     help="Time input: the force channels, by name or 0-based position in "
                     "the file ('none': output-only), when the file does not say."),
        click.option("--quantity", type=click.Choice(QUANTITIES), default=None,
                     help="Time input: the response quantity, when the file does not say."),
    ]
    return _stacked(options, func)


def thresholds_from(shift_sigmas: float | None, min_shift_percent: float | None,
                    min_mac: float | None) -> Thresholds | None:
    """The :class:`~automodal.tracking.Thresholds` of the options given (the defaults for
    the others), or ``None`` when none was given."""
    given = {"k_sigma": shift_sigmas, "min_mac": min_mac,
             "min_relative_shift": None if min_shift_percent is None else min_shift_percent / 100}
    given = {k: v for k, v in given.items() if v is not None}
    if not given:
        return None
    from automodal.tracking import Thresholds

    return Thresholds(**given)
