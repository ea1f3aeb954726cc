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


def time_input_options(func: Callable) -> Callable:
    """``--sample-rate``, ``--forces`` and ``--quantity``: what a file of samples does not say
    (``docs/time-input.md``)."""
    from automodal.frfdata import QUANTITIES

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
    for option in reversed(options):
        func = option(func)
    return func
