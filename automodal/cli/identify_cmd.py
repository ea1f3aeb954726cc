"""``automodal identify``: the whole pipeline on one file."""

from __future__ import annotations

import os
import sys
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import click

from automodal.cli._common import (
    EXIT_INPUT,
    EXIT_MONITORING,
    EXIT_OK,
    REPORT_SUFFIXES,
    check_output_folder,
    check_outputs_spare_inputs,
    debug_option,
    exit_on_error,
    threshold_options,
    thresholds_from,
    time_input_options,
)
from automodal.errors import InputError
from automodal.settings import RESAMPLE_CHOICES

if TYPE_CHECKING:
    from automodal.app.batch import FileOutcome
    from automodal.report_model import Report
    from automodal.settings import Settings
    from automodal.tracking import Thresholds


def _check_outputs(outputs: tuple[str, ...]) -> None:
    for out in outputs:
        if Path(out).suffix.lower() not in REPORT_SUFFIXES:
            raise InputError(
                "unknown report type: the suffix must be .json or .h5", out
            )
        check_output_folder(out, "report")


@contextmanager
def _quiet_warnings(debug: bool) -> Iterator[None]:
    """Keep Python warnings off stderr (unless ``debug``), in this process and in the worker
    processes it starts.

    Stderr carries at most the one error line (cron mails whatever is printed); what
    matters for a run is in the report's warnings. NumPy's RuntimeWarnings on extreme (but
    accepted) data and libraries' notices would otherwise add lines.
    """
    if debug:
        yield
        return
    saved = os.environ.get("PYTHONWARNINGS")
    os.environ["PYTHONWARNINGS"] = "ignore"  # inherited by joblib's worker processes
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        if saved is None:
            os.environ.pop("PYTHONWARNINGS", None)
        else:
            os.environ["PYTHONWARNINGS"] = saved


def read_baseline(path: str) -> Report:
    """Read the ``--baseline`` report (a refusal names the file and exits 2; so does a
    baseline without a physical mode, :func:`automodal.app.monitoring.check_baseline`)."""
    from automodal.app.monitoring import check_baseline
    from automodal.io.report import load_report

    return check_baseline(load_report(path), path)


def _batch_outdir(outputs: tuple[str, ...]) -> Path:
    """The one ``-o OUTDIR`` of a batch run (made by the batch when missing, with the
    folders above it)."""
    if len(outputs) != 1:
        raise InputError("a batch run (a folder or a glob as INPUT) needs exactly one -o OUTDIR")
    out = Path(outputs[0])
    if out.exists() and not out.is_dir():
        raise InputError("is not a folder: a batch run writes its reports into -o OUTDIR",
                         str(out))
    if not out.exists() and out.suffix.lower() in REPORT_SUFFIXES:
        # a report's name, not a folder's: a batch would make a folder called rep.json
        raise InputError("is the name of one report, but a batch run writes one report per"
                         " file into a folder: give -o OUTDIR", str(out))
    if not out.exists():
        check_output_folder(out, "output folder")
    elif not os.access(out, os.W_OK | os.X_OK):
        raise InputError("the output folder is not writable", str(out))
    return out


def _run_batch(input_path: str, outputs: tuple[str, ...], settings: Settings,
               baseline: Report | None, baseline_path: str | None,
               thresholds: Thresholds | None, report_format: str, force: bool, jobs: int | None,
               dask_scheduler: str | None, as_json: bool, quiet: bool) -> int:
    """Batch mode of ``identify``: every file of a folder or glob; returns the exit status."""
    from automodal.app.batch import expand_inputs, run_batch

    outdir = _batch_outdir(outputs)
    prose: list[Path] = []
    files = expand_inputs(input_path, exclude=outdir, left_out=prose)
    if not files:
        raise InputError("no input file found" + (f" ({len(prose)} text file(s) without a "
                         "row of numbers left out)" if prose else ""), input_path)
    talk = not (quiet or as_json)
    if prose and not quiet:
        click.echo(f"automodal: note: left out {len(prose)} text file(s) without a row of "
                   f"numbers: {', '.join(f.name for f in prose)}", err=True)

    def show(outcome: FileOutcome) -> None:
        if outcome.status == "failed":
            click.echo(f"automodal: error: {outcome.file}: {outcome.error}", err=True)
            return
        if talk:
            freqs = ", ".join(f"{f:.4g}" for f in outcome.frequencies_hz if f is not None)
            what = "up to date, not identified again" if outcome.status == "skipped" else (
                f"{outcome.n_physical} physical modes ({freqs or '-'} Hz)")
            click.echo(f"{outcome.file}: {what}")
        if outcome.status == "flagged" and not quiet:
            for line in outcome.flagged_modes:
                click.echo(f"{outcome.file}: {line}", err=as_json)

    result = run_batch(files, outdir, settings, formats=report_format, baseline=baseline,
                       baseline_path=baseline_path, thresholds=thresholds, force=force, jobs=jobs,
                       scheduler_address=dask_scheduler, progress=show, spec=input_path)
    if as_json:
        click.echo(result.summary_json.read_text(encoding="utf-8"), nl=False)
    elif not quiet:
        counts = ", ".join(f"{result.count(s)} {s}" for s in ("ok", "flagged", "failed", "skipped"))
        click.echo(f"{len(result.outcomes)} files: {counts}; summary in {result.summary_json}")
    if result.any_flagged:
        return EXIT_MONITORING
    return EXIT_INPUT if result.any_failed else EXIT_OK


@click.command()
@click.argument("input_path", metavar="INPUT", type=click.Path())
@click.option("-o", "--output", "outputs", multiple=True, metavar="REPORT",
              help="Write a report (.json or .h5); may be given several times.")
@click.option("--json", "as_json", is_flag=True, help="Print the JSON report instead of the table.")
@click.option("--all", "show_all", is_flag=True,
              help="List every surviving cluster in the table, the ones not called physical "
              "too (default: the physical modes only).")
@click.option("-q", "--quiet", is_flag=True,
              help="Print nothing unless something is wrong (for cron): no table, no "
              "warnings (they stay in the report), only errors and flagged modes' exit 3.")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the bootstrap.")
@click.option("--bootstrap", "n_bootstrap", type=click.IntRange(2, 100000), default=100,
              show_default=True, help="Bootstrap replicates.")
@click.option("--resample", type=click.Choice(RESAMPLE_CHOICES),
              default="auto", show_default=True,
              help="What each bootstrap replicate resamples: the repeated records, the "
              "frequency lines, or fresh noise of the noise model around the reference "
              "model (docs/method.md 4). auto: the records when their mean is the FRF, "
              "else the lines. The report's warnings say which ran.")
@click.option("--band", nargs=2, type=float, metavar="FMIN FMAX", default=None,
              help="Analysed band in Hz (default: the data's span).")
@click.option("--order", "max_order", type=click.IntRange(4, 5000), default=None,
              help="Largest model order considered, in states: two per mode, so --order 12 "
              "finds at most 6 modes (default: automatic; a warning says when the order "
              "stopped the model short of the data).")
@click.option("--block-rows", type=click.IntRange(2, 10000), default=None, metavar="Q",
              help="At least Q block rows (2-10000) in the reference model and its "
              "replicates (default: automatic, ceil(1.2 n / r) + 1 for n states and r output "
              "directions above the noise; a band whose refinement cannot confirm a physical mode "
              "is analysed again at the order scan's rows). Many sensors on close modes may "
              "need more (docs/method.md 1); slower.")
@click.option("--one-band", is_flag=True,
              help="Identify the band with one model even when it is costly (by default a "
              "band whose one model would be slow is split into sub-bands at the valleys "
              "between resonances, docs/method.md 2.1).")
@click.option("--jobs", type=click.IntRange(min=1), default=None,
              help="Cores to use (>= 1): threads for one file's bootstrap, sub-bands and "
              "refinement, processes across the "
              "files of a batch. Default: automatic (all cores when the work pays for them). "
              "Never changes the result.")
@click.option("--plot", "plot_dir", type=click.Path(file_okay=False), default=None, metavar="DIR",
              help="Also write the standard figures (PNG) into DIR.")
@click.option("--geometry", "geometry_path", type=click.Path(), default=None, metavar="FILE",
              help="Node coordinates and channel nodes/directions (CSV, or UFF/UNV datasets"
              " 15/2411: docs/cli.md, 'Geometry') for the shape figures and automodal export.")
@click.option("--baseline", "baseline_path", type=click.Path(), default=None, metavar="REPORT",
              help="Check the modes against a baseline report: exit 3 when a mode moved, "
              "changed shape or is missing (a 'monitoring' block goes into the report).")
@threshold_options
@click.option("--force", is_flag=True,
              help="Batch: identify again files whose report is up to date.")
@click.option("--format", "report_format", type=click.Choice(["json", "h5", "both"]),
              default="json", show_default=True, help="Batch: report files per input.")
@click.option("--dask-scheduler", default=None, metavar="ADDRESS",
              help="Batch: run the files on an existing Dask cluster (tcp://host:8786).")
@time_input_options
@debug_option
def identify(
    input_path: str,
    outputs: tuple[str, ...],
    as_json: bool,
    show_all: bool,
    quiet: bool,
    seed: int,
    n_bootstrap: int,
    resample: str,
    band: tuple[float, float] | None,
    max_order: int | None,
    block_rows: int | None,
    jobs: int | None,
    plot_dir: str | None,
    geometry_path: str | None,
    baseline_path: str | None,
    shift_sigmas: float | None,
    min_shift_percent: float | None,
    min_mac: float | None,
    force: bool,
    report_format: str,
    dask_scheduler: str | None,
    sample_rate: float | None,
    forces: str | None,
    quantity: str | None,
    debug: bool,
    one_band: bool = False,
) -> None:
    """Identify the modes in INPUT (an automodal FRF file) with no human choice.

    Prints a table of the physical modes, numbered 1, 2, ... by frequency (every cluster
    with --all; the JSON report with --json), and writes each -o report. The report's
    warnings (a band edge on a resonance, reciprocity assumed, lines left out, ...) follow
    the table on stderr, one line each; --quiet and --json leave them in the report only.
    INPUT may hold FRFs or time records (docs/time-input.md: --sample-rate, --forces and
    --quantity say what a file of samples does not).

    INPUT may also be a folder or a quoted glob: a batch run, one report per file in the
    folder -o OUTDIR with summary.json and summary.csv; files whose report is up to date
    are skipped. Exit status 2 when a file failed (the batch goes on), 3 when --baseline
    flagged a mode.

    A report is written whole or not at all. One that cannot be written (a read-only
    folder, a full disk) ends the run with exit status 2 and one line on stderr naming it.

    \b
    Examples:
      automodal identify sample_data/chain6.h5
      automodal identify test.h5 -o report.json -o report.h5 --seed 1 --quiet
      automodal identify test.h5 -o report.h5 --plot figures/
      automodal identify today.h5 -o today.json --baseline baseline.json
      automodal identify 'incoming/*.h5' -o reports/ --baseline baseline.json --quiet
      automodal identify hits.npy --sample-rate 25600 --forces 1
    """
    with exit_on_error(debug), _quiet_warnings(debug):
        from automodal.app.run import is_batch_input
        from automodal.settings import Settings

        settings = Settings(
            band_hz=tuple(band) if band else None,
            n_bootstrap=n_bootstrap,
            seed=seed,
            max_order=max_order,
            block_rows=block_rows,
            jobs=jobs,
            sub_bands=not one_band,
            resample=resample,
        )
        from automodal.app.run import time_options

        options = time_options(sample_rate, forces, quantity)
        batch = is_batch_input(input_path)
        if batch and options is not None:
            raise InputError(f"{', '.join(options.given)} are for one file: convert each file "
                             "with them to an FRF file first (automodal convert)")
        if batch and plot_dir:
            raise InputError("--plot is for one file: draw a batch's reports with automodal plot")
        if not batch and dask_scheduler:
            raise InputError("--dask-scheduler is for batch runs (a folder or a glob as INPUT)")
        if not batch:
            _check_outputs(outputs)
            check_outputs_spare_inputs(outputs, [input_path, baseline_path, geometry_path])
        if plot_dir:
            from automodal.cli.plot_cmd import check_figure_folder

            check_figure_folder(plot_dir)
        thresholds = thresholds_from(shift_sigmas, min_shift_percent, min_mac)
        if thresholds is not None and not baseline_path:
            raise InputError("--shift-sigmas, --min-shift-percent and --min-mac are "
                             "thresholds of the --baseline check: give --baseline too")
        baseline = read_baseline(baseline_path) if baseline_path else None
        geometry = None
        if geometry_path:
            from automodal.io.geometry import read_geometry

            geometry = read_geometry(geometry_path)
        if batch:
            sys.exit(_run_batch(input_path, outputs, settings, baseline, baseline_path,
                                thresholds, report_format, force, jobs, dask_scheduler,
                                as_json, quiet))
        from automodal.app.run import run_file
        from automodal.cli.progress_display import progress_line, wanted
        from automodal.io.report import format_table

        with progress_line(wanted(quiet, as_json)) as progress:
            outcome = run_file(input_path, settings, outputs, baseline, baseline_path,
                               thresholds, progress=progress, geometry=geometry,
                               options=options)
        if plot_dir:
            from automodal.app.plots import save_figures

            save_figures(outcome.report, None, plot_dir)
        if as_json:
            import json

            click.echo(json.dumps(outcome.report.to_dict(), indent=2))
        elif not quiet:
            click.echo(format_table(outcome.result, show_all=show_all))
            for warning in outcome.report.warnings:
                click.echo(f"automodal: warning: {warning}", err=True)
        check = outcome.check
        if check is not None and not quiet:
            for entry in check.flagged_entries:
                click.echo(f"{input_path}: {entry.message}", err=as_json)
            if not as_json:
                matched = sum(e.status in ("ok", "changed") for e in check.entries)
                click.echo(f"against {baseline_path}: {len(check.flagged_entries)} flagged, "
                           f"{matched} baseline modes matched")
        if check is not None and check.flagged:
            sys.exit(EXIT_MONITORING)
