"""The ``automodal`` command line: a thin click layer over :mod:`automodal.app` and the I/O.

Each command lives in its own module and is imported only when it runs, so that
``automodal --help`` stays fast.
"""

from __future__ import annotations

import importlib
import sys
from typing import Any

import click

from automodal import __version__

# command name -> (module, attribute, one-line help)
_COMMANDS = {
    "calibrate": ("automodal.cli.calibrate_cmd", "calibrate",
                  "Calibrate an FE model to an FRF file, with bootstrap bounds."),
    "convert": ("automodal.cli.convert_cmd", "convert",
                "Convert UFF/UNV, CSV or NPZ FRFs to an FRF file."),
    "design": ("automodal.cli.design_cmd", "design",
               "Design the frequency lines to measure for the expected modes."),
    "export": ("automodal.cli.export_cmd", "export",
               "Write the physical mode shapes as UFF dataset 55 or CSV."),
    "identify": ("automodal.cli.identify_cmd", "identify", "Identify the modes in an FRF file."),
    "plot": ("automodal.cli.plot_cmd", "plot", "Draw the figures of a report."),
    "simulate": ("automodal.cli.simulate_cmd", "simulate",
                 "Write a synthetic test of a known system."),
    "track": ("automodal.cli.track_cmd", "track", "Track modes over time from many reports."),
}


class _LazyGroup(click.Group):
    """A click group that imports a command's module only when the command is used."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(_COMMANDS)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in _COMMANDS:
            return None
        module, attr, _ = _COMMANDS[cmd_name]
        return getattr(importlib.import_module(module), attr)

    def main(self, *args: Any, **kwargs: Any) -> Any:
        """Run the command line; bad usage (an unknown option, a value out of range) ends in
        one line on stderr and exit status 2, like every other bad input."""
        kwargs["standalone_mode"] = False
        try:
            rv = super().main(*args, **kwargs)
        except click.UsageError as exc:
            where = exc.ctx.command_path if exc.ctx is not None else "automodal"
            message = " ".join(exc.format_message().split())
            click.echo(f"automodal: error: {message} (see '{where} --help')", err=True)
            sys.exit(2)
        except click.ClickException as exc:
            exc.show()
            sys.exit(exc.exit_code)
        except click.Abort:
            click.echo("Aborted!", err=True)
            sys.exit(1)
        sys.exit(rv if isinstance(rv, int) else 0)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        rows = [(name, _COMMANDS[name][2]) for name in self.list_commands(ctx)]
        with formatter.section("Commands"):
            formatter.write_dl(rows)


@click.group(cls=_LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="automodal")
def main() -> None:
    """automodal: find the modes of a structure from vibration test data, with no human in the loop.

    \b
    Example:
      automodal identify sample_data/chain6.h5 -o report.json
    """
