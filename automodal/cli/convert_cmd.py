"""``automodal convert``: any supported input (UFF/UNV, CSV, NPZ, FRF file) to an FRF file."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import click

from automodal.cli._common import (
    check_hdf5_suffix,
    check_output_folder,
    check_outputs_spare_inputs,
    checked_test_date,
    debug_option,
    exit_on_error,
    test_date_option,
    time_input_options,
)
from automodal.errors import InputError

if TYPE_CHECKING:
    from automodal.frfdata import FRFData

def summary(output: Path, data: FRFData) -> str:
    """One line describing what was written.

    Parameters
    ----------
    output : Path
        The FRF file written.
    data : FRFData
        Its content.

    Returns
    -------
    str
        Channels, quantity (marked as assumed when the input did not state it) and lines.
    """
    # the readers' note for a quantity the input does not state starts "not stated"
    assumed = str(data.attributes.get("quantity_source", "")).startswith("not stated")
    quantity = f"{data.quantity} (assumed: not stated in the input)" if assumed else data.quantity
    f = data.frequency
    text = (f"{output}: {data.n_outputs} output(s) x {data.n_inputs} input(s), {quantity}, "
            f"{data.n_freq} lines [{f[0]:.6g}, {f[-1]:.6g}] Hz")
    if data.attributes.get("dropped_0hz_line"):
        text += "; 0 Hz line dropped (NaN or 0+0j)"
    return text


@click.command(
    "convert",
    context_settings={"help_option_names": ["-h", "--help"]},
    epilog="""\b
Examples:
  automodal convert measurement.uff measurement.h5
  automodal convert frfs.csv test.h5 --quiet
  automodal convert beam.uff beam.h5 --geometry nodes.csv --test-date 2024-05-01
  automodal convert hits.npy test.h5 --sample-rate 25600 --forces 1
  automodal convert Hxysv*.txt.gz beam.h5 --stack inputs""",
)
@click.argument("input_paths", metavar="INPUT...", nargs=-1, required=True, type=click.Path())
@click.argument("output", metavar="OUTPUT.h5", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--geometry", metavar="FILE", type=click.Path(),
              help="Node coordinates and channel nodes/directions (CSV, or UFF/UNV datasets"
                   " 15/2411: docs/cli.md, 'Geometry'): written as the outputs' nodes,"
                   " directions and xyz.")
@click.option("--stack", type=click.Choice(["inputs", "outputs"]), default=None,
              help="Several INPUT files of FRFs make one test: each file's FRFs become"
                   " further inputs (one file per hammer point) or outputs (one file per"
                   " sensor position), in the order given. Needed with more than one INPUT.")
@test_date_option
@click.option("-q", "--quiet", is_flag=True, help="Print nothing on success.")
@time_input_options
@debug_option
def convert(input_paths: tuple[str, ...], output: Path, geometry: str | None,
            stack: str | None, test_date: str | None, quiet: bool,
            sample_rate: float | None, forces: str | None, quantity: str | None,
            debug: bool) -> None:
    """Convert INPUT to an automodal FRF file OUTPUT.h5 (docs/frf-file.md).

    INPUT is a UFF/UNV file with dataset 58 FRFs (.uff, .unv), a CSV or text table
    (.csv, .txt, also gzipped, .txt.gz; UTF-8 or Latin-1: frequency, then real/imaginary
    column pairs, one input; title and unit lines before the column names are left out,
    as in SignalCalc exports), a NumPy archive
    (.npz: keys frequency and frf) or an FRF file (.h5); or time records (docs/time-input.md:
    .npy, .npz, .csv/.tsv/.txt, .mat, .tdms, .uff, .h5), whose FRFs are written with the
    records themselves in the /time group (sample rate and forces as --sample-rate and
    --forces said), so that OUTPUT can be identified again without the options. Several
    INPUT files of FRFs (one per hammer point or per sensor position) make one test with
    --stack inputs or --stack outputs. OUTPUT is
    written atomically: it is replaced only once complete. Prints one summary line unless
    --quiet.
    """
    with exit_on_error(debug):
        when = None if test_date is None else checked_test_date(test_date)
        check_hdf5_suffix(output, "FRF file")
        check_output_folder(output, "FRF file")
        check_outputs_spare_inputs([output], [*input_paths, geometry])
        for input_path in input_paths:
            if Path(input_path).is_dir():
                raise InputError("is a folder, not an input file", input_path)
        if len(input_paths) > 1 and stack is None:
            raise InputError(f"{len(input_paths)} input files: say how they make one test, "
                             "--stack inputs (one file per hammer point) or --stack outputs "
                             "(one file per sensor position)")
        from automodal.app.run import time_options
        from automodal.io.frf_file import write_frf
        from automodal.io.readers import read_any
        from automodal.pipeline import input_stage
        from automodal.timedata import TimeSeries

        options = time_options(sample_rate, forces, quantity)
        if len(input_paths) > 1:
            read = _stacked_files(input_paths, stack or "inputs", options)
        else:
            read = read_any(input_paths[0], options)
        data = input_stage(read)  # the FRFs identify would analyse (output-only: 2 passes)
        if geometry:
            from automodal.io.geometry import apply_to_data, read_geometry

            data = apply_to_data(data, read_geometry(geometry))
        if when is not None:
            data.attributes["test_date"] = when
        if isinstance(data.attributes.get("time_analysis"), dict):  # HDF5 has no dict type
            import json

            data.attributes["time_analysis"] = json.dumps(data.attributes["time_analysis"])
        write_frf(output, data, time=read if isinstance(read, TimeSeries) else None)
        if not quiet:
            click.echo(summary(output, data))


def _stacked_files(paths: tuple[str, ...], along: str, options: object) -> FRFData:
    """The FRFs of several files as one test (:func:`automodal.io.stacking.stack_frfs`);
    time records are refused (each is a test of its own)."""
    from automodal.frfdata import FRFData
    from automodal.io.readers import read_any
    from automodal.io.stacking import stack_frfs

    parts = []
    for path in paths:
        read = read_any(path, options)  # type: ignore[arg-type]
        if not isinstance(read, FRFData):
            raise InputError("holds time records; only files of FRFs are stacked (convert "
                             "time records one file at a time)", path)
        parts.append(read)
    return stack_frfs(parts, along)
