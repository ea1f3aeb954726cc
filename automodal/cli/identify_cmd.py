"""``automodal identify``: the whole pipeline on one file."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from automodal.cli._common import debug_option, exit_on_error
from automodal.errors import InputError

REPORT_SUFFIXES = (".json", ".h5", ".hdf5")


def _check_outputs(outputs: tuple[str, ...]) -> None:
    for out in outputs:
        if Path(out).suffix.lower() not in REPORT_SUFFIXES:
            raise InputError(
                "unknown report type: the suffix must be .json or .h5", out
            )
        parent = Path(out).parent
        if not parent.is_dir():
            raise InputError("the report's folder does not exist", out)


def read_input(path: str):
    """Read any supported input file into an :class:`FRFData` (see :func:`read_any`)."""
    p = Path(path)
    if p.is_dir():
        raise InputError("is a folder; batch runs over folders are not supported yet", path)
    from automodal.io.readers import read_any

    return read_any(path)


@click.command()
@click.argument("input_path", metavar="INPUT", type=click.Path())
@click.option("-o", "--output", "outputs", multiple=True, metavar="REPORT",
              help="Write a report (.json or .h5); may be given several times.")
@click.option("--json", "as_json", is_flag=True, help="Print the JSON report instead of the table.")
@click.option("-q", "--quiet", is_flag=True, help="Print nothing unless something is wrong (for cron).")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the bootstrap.")
@click.option("--bootstrap", "n_bootstrap", type=click.IntRange(2, 100000), default=100,
              show_default=True, help="Bootstrap replicates.")
@click.option("--band", nargs=2, type=float, metavar="FMIN FMAX", default=None,
              help="Analysed band in Hz (default: the data's span).")
@click.option("--order", "max_order", type=click.IntRange(4, 5000), default=None,
              help="Largest model order (states) considered (default: automatic).")
@click.option("--jobs", type=int, default=None,
              help="Processes for the bootstrap (default: all cores); never changes the result.")
@click.option("--plot", "plot_dir", type=click.Path(file_okay=False), default=None, metavar="DIR",
              help="Also write the standard figures (PNG) into DIR.")
@debug_option
def identify(
    input_path: str,
    outputs: tuple[str, ...],
    as_json: bool,
    quiet: bool,
    seed: int,
    n_bootstrap: int,
    band: tuple[float, float] | None,
    max_order: int | None,
    jobs: int | None,
    plot_dir: str | None,
    debug: bool,
) -> None:
    """Identify the modes in INPUT (an automodal FRF file) with no human choice.

    Prints a table of modes (or the JSON report with --json) and writes each -o report.

    \b
    Examples:
      automodal identify sample_data/chain6.h5
      automodal identify test.h5 -o report.json -o report.h5 --seed 1 --quiet
      automodal identify test.h5 -o report.h5 --plot figures/
    """
    with exit_on_error(debug):
        _check_outputs(outputs)
        data = read_input(input_path)
        from automodal.io.report import format_table, report_dict, save_report
        from automodal.pipeline import Settings
        from automodal.pipeline import identify as run

        settings = Settings(
            band_hz=tuple(band) if band else None,
            n_bootstrap=n_bootstrap,
            seed=seed,
            max_order=max_order,
            jobs=jobs,
        )
        show_bar = not quiet and sys.stderr.isatty()
        if show_bar:
            with click.progressbar(length=n_bootstrap, label="bootstrap", file=sys.stderr) as bar:
                result = run(data, settings, progress=bar.update)
        else:
            result = run(data, settings)
        report = report_dict(result, data, input_path=input_path)
        for out in outputs:
            save_report(out, report, result.poles, frf=result.frf_fit)
        if plot_dir:
            from automodal.plots import save_figures

            save_figures(report, {"poles": result.poles, "frf": result.frf_fit}, plot_dir)
        if as_json:
            import json

            click.echo(json.dumps(report, indent=2))
        elif not quiet:
            click.echo(format_table(result))
