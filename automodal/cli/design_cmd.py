"""``automodal design``: the frequency lines to measure for a band and the expected modes."""

from __future__ import annotations

from pathlib import Path

import click

from automodal.cli._common import (
    FiniteFloatRange,
    check_output_folder,
    check_outputs_spare_inputs,
    debug_option,
    exit_on_error,
)


@click.command(
    "design",
    context_settings={"help_option_names": ["-h", "--help"]},
    epilog="""\b
Examples:
  automodal design --band 2 40 --lines 200 --mode 3.84:0.01 --mode 11.3:0.006 -o lines.csv
  automodal design --band 2 40 --lines 200 --modes report.h5 -o lines.json
  automodal design --band 2 40 --lines 200 --modes modes.csv --uncertainty 2 -o lines.csv""",
)
@click.option("--band", nargs=2, type=float, required=True, metavar="LOW HIGH",
              help="The band in Hz; both edges are lines.")
@click.option("--lines", "n_lines", type=int, required=True, metavar="N",
              help="Number of lines to measure.")
@click.option("--mode", "modes", multiple=True, metavar="F:ZETA",
              help="An expected mode: natural frequency (Hz) and damping ratio, e.g."
                   " 12.5:0.01 (repeat for more).")
@click.option("--modes", "modes_file", type=click.Path(), metavar="FILE",
              help="Expected modes from a report (.json/.h5, its physical modes), a modes"
                   " file of 'automodal simulate', or a CSV with columns frequency_hz and"
                   " damping_ratio.")
@click.option("--rule", type=click.Choice(["modal", "dt-uniform", "equidistant", "d-optimal"]),
              default="modal", show_default=True,
              help="modal: lines on each mode's resonance plus a background uniform on the"
                   " unit circle (docs/design.md); the others for comparison.")
@click.option("--uncertainty", type=FiniteFloatRange(min=0, max=50), default=0.0,
              show_default=True, metavar="PERCENT",
              help="How far off the expected frequencies may be; widens each mode's lines.")
@click.option("-o", "--output", "outputs", multiple=True, required=True, metavar="FILE",
              type=click.Path(dir_okay=False, path_type=Path),
              help="Write the lines to FILE: .csv (column frequency_hz) or .json (with the"
                   " lines per mode); repeatable.")
@click.option("-q", "--quiet", is_flag=True, help="Print nothing on success.")
@debug_option
def design(band: tuple[float, float], n_lines: int, modes: tuple[str, ...],
           modes_file: str | None, rule: str, uncertainty: float, outputs: tuple[Path, ...],
           quiet: bool, debug: bool) -> None:
    """Design the N frequency lines at which to measure FRFs over a band, given the modes
    expected there, for automodal's subspace identification.

    The default rule gives each expected mode lines evenly spaced in its resonance's phase
    (half of them inside its half-power band) and spreads the rest evenly over the band as
    the identification sees it on the unit circle. Prints one line per mode (its lines in
    the half-power band) unless --quiet. Nothing is written when an input is refused.
    """
    with exit_on_error(debug):
        from automodal.app.design import design as make_design
        from automodal.io.line_design_files import design_suffix, write_design

        for out in outputs:
            design_suffix(out)
            check_output_folder(out, "lines file")
        check_outputs_spare_inputs(outputs, [modes_file])
        d, left = make_design(band, n_lines, modes, modes_file, rule, uncertainty / 100.0)
        for out in outputs:
            write_design(out, d, band)
        if quiet:
            return
        if left:
            click.echo(f"automodal: note: {left} expected mode(s) outside the band left out",
                       err=True)
        for fr, zr, c in zip(d.mode_frequency_hz, d.mode_damping_ratio, d.half_power_lines,
                             strict=True):
            click.echo(f"mode {fr:.6g} Hz, damping {100 * zr:.3g} %: {c} line(s) in its"
                       " half-power band")
        click.echo(f"{d.frequency_hz.size} lines ({d.rule}) written to "
                   + ", ".join(str(o) for o in outputs))
