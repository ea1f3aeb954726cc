"""Helpers shared by the CLI commands: turning errors into exit statuses."""

from __future__ import annotations

import sys
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import click

from automodal.errors import InputError

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
    is printed too.
    """
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
    except Exception as exc:  # noqa: BLE001 - the CLI boundary
        if debug:
            traceback.print_exc()
        msg = " ".join(str(exc).split()) or type(exc).__name__
        click.echo(f"automodal: internal error: {type(exc).__name__}: {msg}", err=True)
        sys.exit(EXIT_INTERNAL)


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
