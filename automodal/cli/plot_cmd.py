"""``automodal plot``: figures from a report, without identifying anything again."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import click

from automodal.cli._common import (
    check_output_folder,
    check_outputs_spare_inputs,
    debug_option,
    exit_on_error,
)
from automodal.errors import InputError

if TYPE_CHECKING:
    from automodal.report_model import ReportArrays

FIGURE_SUFFIXES = (".png", ".svg", ".pdf")


def default_output(report: str) -> Path:
    """``<report stem>.png`` beside the report."""
    return Path(report).with_suffix(".png")


def _check_output(out: Path) -> None:
    """Refuse an unknown figure format or a folder that cannot be made, before any work."""
    if out.suffix.lower() not in FIGURE_SUFFIXES:
        raise InputError(
            f"unknown figure type {out.suffix or '(none)'!r}: use .png, .svg or .pdf", str(out)
        )
    check_output_folder(out, "figure")


def check_figure_folder(folder: str | Path) -> None:
    """Refuse, before any work, a folder of figures that can be neither found nor made (it
    is made when missing, with the folders above it)."""
    check_output_folder(Path(folder) / "overview.png", "figure")


def _missing(report_path: str, arrays: ReportArrays) -> str | None:
    """One line naming what the report lacks for a full figure, or None."""
    needs = ((arrays.poles, "bootstrap poles"), (arrays.frf, "FRFs"))
    lacks = [what for found, what in needs if not found]
    if not lacks:
        return None
    return (
        f"automodal: note: {report_path} has no {' and no '.join(lacks)}:"
        f" plotting only {'physicalness and mode shapes' if len(lacks) == 2 else 'the rest'}"
    )


@click.command()
@click.argument("report_path", metavar="REPORT", type=click.Path())
@click.option("-o", "--output", default=None, metavar="FIGURE|DIR",
              help="Figure file, .png, .svg or .pdf (default: <REPORT stem>.png beside REPORT);"
                   " a folder (existing, or a name without suffix) gets the standard set of"
                   " figures as PNG files.")
@click.option("--geometry", metavar="FILE", type=click.Path(),
              help="Node coordinates and channel nodes/directions (CSV, or UFF/UNV datasets"
                   " 15/2411: docs/cli.md, 'Geometry') for the mode-shape figure.")
@click.option("--dpi", type=click.IntRange(20, 1200), default=150, show_default=True,
              help="Resolution of a PNG.")
@debug_option
def plot(report_path: str, output: str | None, geometry: str | None, dpi: int,
         debug: bool) -> None:
    """Draw the overview figure of REPORT (a .json or .h5 report of automodal identify),
    or the trends of a history file of automodal track.

    The figure holds the stabilization diagram (the order scan's poles against model
    order, stable ones marked), the bootstrap poles by cluster with the Trashbox over the FRF, the
    measured FRFs against those synthesized from the physical modes, the physicalness of
    every cluster, and the physical mode shapes (on the sensor geometry when it is known).
    An HDF5 report holds everything; a JSON report has no poles nor FRFs, and only the
    physicalness and the shapes are drawn. A history file (automodal track) gives the
    frequency change and damping of each tracked mode over time with bootstrap bands,
    flagged points ringed in red. With -o DIR (a folder) the standard set is written
    instead: overview, stabilization, poles, frf_fit, physicalness, mode_shapes and automac
    (.png). Prints the path of each figure written.

    \b
    Examples:
      automodal plot report.h5
      automodal plot report.h5 -o modes.svg
      automodal plot report.h5 -o figures/ --geometry nodes.csv
      automodal plot history.h5 -o trends.png
    """
    with exit_on_error(debug):
        out = Path(output) if output else default_output(report_path)
        folder = out.is_dir() or (output is not None and not out.suffix)
        if folder:
            check_figure_folder(out)
        else:
            _check_output(out)
            check_outputs_spare_inputs([out], [report_path, geometry])
        from automodal.io.history import is_history_file

        if is_history_file(report_path):
            if folder:
                raise InputError("a history file gives one figure: name a .png, .svg or"
                                 " .pdf file with -o", str(out))
            _plot_history(report_path, out, dpi)
            return
        from automodal.io.report import load_report

        report = load_report(report_path, arrays=True)
        if geometry:
            from automodal.io.geometry import apply_to_report, read_geometry

            apply_to_report(report, read_geometry(geometry))
        note = _missing(report_path, report.arrays)
        if note:
            click.echo(note, err=True)

        import matplotlib

        matplotlib.use("Agg")
        from automodal.app.plots import overview, save_figure, save_figures

        if folder:
            for path in save_figures(report, None, out, dpi):
                click.echo(str(path))
            return
        fig = overview(report, report.arrays.poles, report.arrays.frf,
                       stabilization=report.arrays.stabilization)
        save_figure(fig, out, dpi=dpi)
        click.echo(str(out))


def _plot_history(path: str, out: Path, dpi: int) -> None:
    """The trend figure of a history file, written to ``out``; prints its path."""
    from automodal.io.history import read_history

    history = read_history(path)
    import matplotlib

    matplotlib.use("Agg")
    from automodal.app.plots import save_figure, trend

    save_figure(trend(history), out, dpi=dpi)
    click.echo(str(out))
