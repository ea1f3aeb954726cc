"""``automodal calibrate``: an FE model calibrated to an FRF file, with bootstrap bounds."""

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
from automodal.errors import InputError


@click.command(
    "calibrate",
    context_settings={"help_option_names": ["-h", "--help"]},
    epilog="""\b
Examples:
  automodal calibrate test.h5 model.h5 -o result.json
  automodal calibrate test.h5 model.h5 -o result.json --seed 1 --bootstrap 200 --plot figures/
  automodal calibrate beam.h5 beam_model.h5 -o r.json --band 65 1000""",
)
@click.argument("frf_path", metavar="FRF_FILE", type=click.Path())
@click.argument("model_path", metavar="MODEL_FILE", type=click.Path())
@click.option("-o", "--output", required=True, metavar="FILE.json",
              type=click.Path(dir_okay=False, path_type=Path),
              help="The result (JSON, docs/calibrate.md), written atomically.")
@click.option("--seed", type=click.IntRange(min=0, max=2**63 - 1), default=0, show_default=True,
              help="Seed of the bootstrap; the same seed gives the same result whatever --jobs.")
@click.option("--bootstrap", "n_bootstrap", type=click.IntRange(min=2), default=100,
              show_default=True, help="Bootstrap datasets calibrated.")
@click.option("--jobs", type=click.IntRange(min=1), default=None,
              help="Worker threads.  [default: all cores when it pays]")
@click.option("--band", nargs=2, type=float, default=None, metavar="LO HI",
              help="Band in Hz to identify and calibrate in.  [default: the file's]")
@click.option("--equalization", type=click.Choice(["paired", "common", "none"]),
              default="paired", show_default=True,
              help="Damping equalization: each FE mode the damping of its test mode, one "
                   "common ratio for both models (--common-damping), or none.")
@click.option("--common-damping", type=FiniteFloatRange(0, 1, min_open=True, max_open=True),
              default=0.05, show_default=True, help="The ratio of --equalization common.")
@click.option("--plot", "plot_dir", metavar="DIR", type=click.Path(file_okay=False),
              default=None, help="Write the figures (FRF overlay, parameter distributions).")
@click.option("-q", "--quiet", is_flag=True, help="Print nothing on success.")
@debug_option
def calibrate(frf_path: str, model_path: str, output: Path, seed: int, n_bootstrap: int,
              jobs: int | None, band: tuple[float, float] | None, equalization: str,
              common_damping: float, plot_dir: str | None, quiet: bool, debug: bool) -> None:
    """Calibrate the FE model of MODEL_FILE (HDF5, docs/calibrate.md) to the FRFs of
    FRF_FILE: identify the test's modes, give each FE mode its test mode's damping, fit the
    parameters to the log FRFs weighted by their signal-to-noise ratio, and repeat on
    bootstrap datasets for each parameter's std and 95 % interval and bounds on the
    predicted modes. Prints a table of the parameters and the modes.
    """
    with exit_on_error(debug):
        if output.suffix.lower() != ".json":
            raise InputError("the result must be a .json file", output)
        check_output_folder(output, "result")
        check_outputs_spare_inputs([output], [frf_path, model_path])
        if plot_dir:
            from automodal.cli.plot_cmd import check_figure_folder

            check_figure_folder(plot_dir)  # before the work, as identify --plot
        from automodal.app.calibrate import (
            CalibrationSettings,
            calibrate_file,
            write_result,
        )

        settings = CalibrationSettings(seed=seed, n_bootstrap=n_bootstrap, jobs=jobs,
                                       band_hz=None if band is None else tuple(band),
                                       equalization=equalization,
                                       common_damping=common_damping)
        from automodal.cli.progress_display import progress_line, wanted

        with progress_line(wanted(quiet)) as progress:
            outcome = calibrate_file(frf_path, model_path, settings, progress)
        write_result(output, outcome.result)
        if plot_dir:
            from automodal.app.calibration_plots import save_calibration_figures

            save_calibration_figures(outcome, plot_dir)
        if not quiet:
            click.echo(format_result(outcome.result))
            for warning in outcome.result["warnings"]:
                click.echo(f"automodal: warning: {warning}", err=True)


def format_result(result: dict) -> str:
    """The parameters and the modes as text tables."""
    lines = ["parameter        value        std             95 % interval",
             "---------  ----------  ---------  -------------------------"]
    for p in result["parameters"]:
        lo, hi = p["ci95"]
        lines.append(f"{p['name']:<9}  {p['value']:10.5f}  {p['std']:9.2e}  "
                     f"[{lo:10.5f}, {hi:10.5f}]")
    lines += ["", "mode  measured (Hz)  nominal FE (Hz)  calibrated FE (Hz)     MAC",
              "----  -------------  ---------------  ------------------  ------"]
    for m in result["modes"]:
        if m["fe_mode"] is None:
            lines.append(f"{m['mode']:4d}  {m['measured_frequency_hz']:13.4f}  (no FE mode"
                         " paired)")
            continue
        lines.append(f"{m['mode']:4d}  {m['measured_frequency_hz']:13.4f}  "
                     f"{m['nominal_frequency_hz']:15.4f}  {m['predicted_frequency_hz']:10.4f}"
                     f" ± {m['predicted_frequency_std_hz']:5.4f}  {m['mac']:6.3f}")
    d = result["deviation"]
    lines.append(f"\nrms log deviation {d['rms_log_before']:.4g} before, "
                 f"{d['rms_log_after']:.4g} after; {result['bootstrap']['converged']} of "
                 f"{result['bootstrap']['n']} bootstrap calibrations; runtime "
                 f"{result['runtime_s']:.1f} s")
    return "\n".join(lines)
