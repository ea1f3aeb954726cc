"""``automodal export``: the physical modes' shapes of a report as UFF dataset 55 or CSV."""

from __future__ import annotations

from pathlib import Path

import click

from automodal.cli._common import (
    check_output_folder,
    check_outputs_spare_inputs,
    debug_option,
    exit_on_error,
)


@click.command(
    "export",
    context_settings={"help_option_names": ["-h", "--help"]},
    epilog="""\b
Examples:
  automodal export report.h5 -o shapes.uff
  automodal export report.json -o shapes.csv --polar
  automodal export report.h5 -o shapes.unv --geometry nodes.csv""",
)
@click.argument("report_path", metavar="REPORT", type=click.Path())
@click.option("-o", "--output", required=True, metavar="FILE",
              type=click.Path(dir_okay=False, path_type=Path),
              help="Output file: .uff or .unv (dataset 55), or .csv.")
@click.option("--polar", is_flag=True,
              help="CSV: magnitude and phase (degrees) instead of real and imaginary parts.")
@click.option("--geometry", metavar="FILE", type=click.Path(),
              help="Nodes and channel directions (CSV, or UFF/UNV datasets 15/2411:"
                   " docs/cli.md, 'Geometry') for the shape channels, when the report lacks"
                   " them.")
@click.option("-q", "--quiet", is_flag=True, help="Print nothing on success.")
@debug_option
def export(report_path: str, output: Path, polar: bool, geometry: str | None, quiet: bool,
           debug: bool) -> None:
    """Write the shapes of the physical modes of REPORT (automodal identify's .json or .h5)
    for FE and animation tools.

    A UFF file holds one dataset 55 (data at nodes, complex eigenvalue) per mode, each
    channel's value at its node and direction; a CSV file one row per mode: mode,
    frequency_hz, damping_ratio, then each channel's shape (real and imaginary parts, or
    magnitude and phase with --polar), named after the channel. Written atomically.
    Prints one summary line unless --quiet.
    """
    with exit_on_error(debug):
        from automodal.io.mode_export import export_modes, export_suffix

        export_suffix(output)  # refused before the report is read
        check_output_folder(output, "export file")
        check_outputs_spare_inputs([output], [report_path, geometry])
        from automodal.io.report import load_report

        report = load_report(report_path)
        if geometry:
            from automodal.io.geometry import apply_to_report, read_geometry

            apply_to_report(report, read_geometry(geometry))
        n = export_modes(output, report, polar)
        if not quiet:
            click.echo(f"{output}: {n} physical mode(s) on {len(report.shape_channels)}"
                       " channel(s)")
