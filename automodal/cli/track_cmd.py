"""``automodal track``: modes of many reports tracked over time into a history file."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click

from automodal.cli._common import (
    EXIT_MONITORING,
    REPORT_SUFFIXES,
    check_hdf5_suffix,
    check_output_folder,
    check_outputs_spare_inputs,
    debug_option,
    exit_on_error,
    threshold_options,
    thresholds_from,
)
from automodal.errors import InputError

SKIPPED_NAMES = ("summary.json",)
"""Files of a folder that are never reports (the batch summary)."""

BATCH_SUMMARY_FORMAT = "automodal-batch-summary"
"""The ``format`` of a batch's summary (``automodal.app.batch.SUMMARY_FORMAT``, not
imported: the command line loads the identification's modules only when it runs)."""


def is_batch_summary(path: Path) -> bool:
    """Whether ``path`` is a batch's ``summary.json`` (by name and by its ``format``)."""
    if path.name not in SKIPPED_NAMES:
        return False
    try:
        head = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(head, dict) and head.get("format") == BATCH_SUMMARY_FORMAT


def report_files(paths: tuple[str, ...]) -> list[str]:
    """The report files named by REPORTS: files as given, folders by their reports.

    A folder gives its ``*.json``, ``*.h5`` and ``*.hdf5`` files (not hidden ones, not the
    batch's ``summary.json``), sorted by name. A batch's summary named among the files (a
    shell's ``reports/*.json`` names it) is left out too.
    """
    files: list[str] = []
    for given in paths:
        p = Path(given)
        if p.is_dir():
            files += sorted(
                str(f) for f in p.iterdir()
                if f.is_file() and f.suffix.lower() in REPORT_SUFFIXES
                and not f.name.startswith(".") and f.name not in SKIPPED_NAMES
            )
        elif not is_batch_summary(p):
            files.append(given)
    return files


@click.command()
@click.argument("reports", metavar="REPORTS...", nargs=-1, required=True, type=click.Path())
@click.option("-o", "--output", required=True, metavar="HISTORY.h5",
              help="The history file to write (HDF5).")
@click.option("--baseline", "baseline_path", default=None, metavar="REPORT", type=click.Path(),
              help="Track and check against this report (default: the earliest of REPORTS).")
@click.option("-q", "--quiet", is_flag=True,
              help="Print nothing unless something is wrong (errors; exit 3 when flagged).")
@threshold_options
@debug_option
def track(reports: tuple[str, ...], output: str, baseline_path: str | None, quiet: bool,
          shift_sigmas: float | None, min_shift_percent: float | None,
          min_mac: float | None, debug: bool) -> None:
    """Track the physical modes of a baseline through REPORTS over time.

    Each report (or every report in a folder) is placed at its test's date (the input
    attribute test_date or date, ISO 8601) or else at the time it was made, matched to the
    baseline's physical modes by frequency and shape, and checked as --baseline does in
    identify. The history file holds frequency and damping with their bootstrap spread per
    mode and time, and which modes were flagged; draw it with automodal plot. Prints one
    line per report. Modes are named by their number in the baseline (mode 1, 2, ... by
    frequency), as in identify's table.

    Exit status 3 when a mode of any report was flagged (as identify --baseline), 2 for
    a report that cannot be read, 0 otherwise. Give --baseline: without it the earliest
    report is the baseline, and a series that starts damaged looks healthy.

    \b
    Examples:
      automodal track reports/ --baseline baseline.json -o history.h5
      automodal track reports/*.json --baseline base.json -o history.h5 --min-shift-percent 1
      automodal plot history.h5
    """
    with exit_on_error(debug):
        out = Path(output)
        check_hdf5_suffix(out, "history file")
        check_output_folder(out, "history file")
        check_outputs_spare_inputs([out], [*reports, baseline_path])
        from automodal.app.monitoring import history_of_files
        from automodal.io.history import write_history

        files = report_files(reports)
        if not files:
            raise InputError("no report found", " ".join(reports))
        history = history_of_files(files, baseline_path,
                                   thresholds_from(shift_sigmas, min_shift_percent, min_mac))
        label = history.baseline_label
        write_history(out, history)
        if not quiet:
            for t in range(history.n_times):
                flagged = [f"mode {int(history.mode_numbers[m])}" for m in range(history.n_modes)
                           if history.mode_flagged[t, m]]
                state = f"flagged: {', '.join(flagged)}" if flagged else "ok"
                click.echo(f"{history.times[t]}  {history.labels[t]}: {state}")
            click.echo(f"{history.n_times} reports, {history.n_modes} modes tracked against "
                       f"{label}; {int(history.flagged.sum())} flagged; written to {out}")
        if history.flagged.any():
            sys.exit(EXIT_MONITORING)
