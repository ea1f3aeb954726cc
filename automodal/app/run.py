"""Run one file: read the input, identify, make the report, check it, write it.

:func:`run_file` is the one path from an input file to its report files, used by
``automodal identify`` on one file (:mod:`automodal.cli.identify_cmd`) and by each file of a
batch (:func:`automodal.app.batch.process_file`). :func:`check_jobs` gives a ``jobs``
argument the meaning :class:`~automodal.settings.Settings` gives its own (which it checks on
creation): ``None`` automatic (all cores when the work pays for them), an integer >= 1 that
many workers; 0 or negative is refused.
"""

from __future__ import annotations

import glob
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from automodal.errors import InputError
from automodal.progress import ProgressCallback, tell

if TYPE_CHECKING:
    from automodal.app.monitoring import MonitoringResult
    from automodal.frfdata import FRFData
    from automodal.io.channels import TimeOptions
    from automodal.io.geometry import Geometry
    from automodal.report_model import Report
    from automodal.result import Result
    from automodal.settings import Settings
    from automodal.tracking import Thresholds

__all__ = ["RunOutcome", "check_jobs", "is_batch_input", "read_input", "run_file", "save",
           "time_options"]


@dataclass
class RunOutcome:
    """What :func:`run_file` made.

    Attributes
    ----------
    report : Report
        The report (with its ``monitoring`` block when checked against a baseline).
    result : Result
        The pipeline's result.
    check : MonitoringResult or None
        The baseline check, when there was a baseline.
    written : list of Path
        The report files written.
    """

    report: Report
    result: Result
    check: MonitoringResult | None = None
    written: list[Path] = field(default_factory=list)

    @property
    def flagged(self) -> bool:
        """Whether the baseline check raised the alarm."""
        return self.check is not None and self.check.flagged


def check_jobs(jobs: int | None) -> int | None:
    """``jobs`` itself if it is ``None`` (automatic) or an integer >= 1.

    Raises
    ------
    InputError
        For 0, a negative number or a non-integer.
    """
    if jobs is None:
        return None
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise InputError(f"jobs must be an integer >= 1 (or None: automatic), not {jobs!r}")
    return jobs


def is_batch_input(spec: str) -> bool:
    """Whether an INPUT asks for a batch (:mod:`automodal.app.batch`): an existing folder,
    or a glob pattern that is not itself an existing file. Here, not in the batch module,
    so that a run on one file does not import the batch machinery."""
    p = Path(spec)
    return p.is_dir() or (not p.exists() and glob.has_magic(spec))


def time_options(sample_rate: float | None = None, forces: str | None = None,
                 quantity: str | None = None) -> TimeOptions | None:
    """The command line's ``--sample-rate``, ``--forces`` and ``--quantity`` as
    :class:`~automodal.io.channels.TimeOptions` (None when none is given).

    ``forces`` is the text of ``--forces``: channel names or 0-based positions separated
    by commas, or ``none``.

    Raises
    ------
    InputError
        For a sample rate that is not > 0, an empty channel name, an unknown quantity.
    """
    if sample_rate is None and forces is None and quantity is None:
        return None
    from automodal.io.channels import TimeOptions, parse_forces

    return TimeOptions(sample_rate=sample_rate, forces=parse_forces(forces), quantity=quantity)


def read_input(
    path: str | os.PathLike[str], options: TimeOptions | None = None,
    settings: Settings | None = None, progress: ProgressCallback | None = None,
) -> FRFData:
    """Read any supported input file as FRFs (:func:`automodal.io.readers.read_any`; time
    series go through the pipeline's input stage, :func:`automodal.pipeline.input_stage`,
    here, so that the report describes the FRFs that were analysed).

    Parameters
    ----------
    path : str or path-like
    options : TimeOptions, optional
        What the user says about a file of samples (:func:`time_options`).
    settings : Settings, optional
        The run's settings (output-only records: the first pass and the band).
    progress : callable, optional
        As in :func:`run_file` (``"reading"``, then the input stage's ``"spectra"`` and first
        pass).

    Raises
    ------
    InputError
        If ``path`` is a folder, or the file cannot be read (or the options do not fit it).
    """
    from automodal.io.readers import start_reading

    tell(progress, "reading")
    pending = start_reading(path, options)
    try:
        from automodal.pipeline import input_stage  # imported while a child process reads
    except BaseException:
        pending.cancel()
        raise
    return input_stage(pending(), settings, progress)


def _own_nodes(path: str | os.PathLike[str], data: FRFData) -> Geometry | None:
    """The nodes of a UFF input that carries them (datasets 15/2411), else None."""
    from automodal.io.geometry import UFF_SUFFIXES, read_geometry

    if Path(path).suffix.lower() not in UFF_SUFFIXES or not data.attributes.get(
            "geometry_source"):
        return None
    return read_geometry(path)


def save(out: str | os.PathLike[str], report: Report, result: Result,
         name: str | os.PathLike[str] | None = None) -> Path:
    """Write one report file (atomically: whole or not at all), with the run's poles and
    FRF fit for an HDF5 report.

    A failure to write (read-only folder, full disk) becomes an :class:`InputError`
    naming the report (``name``, when ``out`` is a temporary file standing in for it).
    """
    from automodal.io.report import save_report

    try:
        save_report(out, report, result.poles, frf=result.frf_fit,
                    stabilization=result.stabilization)
    except OSError as exc:
        reason = exc.strerror or " ".join(str(exc).split()) or type(exc).__name__
        raise InputError(f"cannot write the report: {reason}",
                         os.fspath(out if name is None else name)) from exc
    return Path(out)


def save_all(outputs: Sequence[str | os.PathLike[str]], report: Report,
             result: Result) -> list[Path]:
    """Write every report file, all or none (:func:`automodal.io.atomic.atomic_paths`):
    a run asked for ``-o r.json -o r.h5`` that could write only the first left it
    behind, though it exited 2."""
    from automodal.io.atomic import atomic_paths

    if len(outputs) < 2:
        return [save(out, report, result) for out in outputs]
    try:
        with atomic_paths(outputs) as staged:
            for tmp, out in zip(staged, outputs):
                save(tmp, report, result, name=out)
    except OSError as exc:  # the renames (a full disk fails at the writes)
        reason = exc.strerror or " ".join(str(exc).split()) or type(exc).__name__
        raise InputError(f"cannot write the reports: {reason}",
                         os.fspath(outputs[0])) from exc
    return [Path(out) for out in outputs]


def run_file(
    path: str | os.PathLike[str],
    settings: Settings,
    outputs: Sequence[str | os.PathLike[str]] = (),
    baseline: Report | None = None,
    baseline_path: str | None = None,
    thresholds: Thresholds | None = None,
    progress: ProgressCallback | None = None,
    sha256: str | None = None,
    geometry: Geometry | None = None,
    options: TimeOptions | None = None,
) -> RunOutcome:
    """Identify one input file and write its reports.

    Parameters
    ----------
    path : str or path-like
        The input (any format :func:`automodal.io.readers.read_any` reads).
    settings : Settings
        Settings of the identification (``jobs`` included, checked when they were made).
    outputs : sequence of path-like
        Report files to write (``.json``, ``.h5``), after the baseline check.
    baseline : Report, optional
        A baseline report to check the new one against (its ``monitoring`` block).
    baseline_path : str, optional
        Where the baseline came from (recorded in the block, named in messages).
    thresholds : Thresholds, optional
        Of the baseline check.
    progress : callable, optional
        Called with a :class:`~automodal.progress.Progress` as each stage starts (reading,
        the identification's, writing) and as the bootstrap replicates finish.
    sha256 : str, optional
        The SHA-256 of the input when the caller has hashed it already (see
        :func:`automodal.io.report.build_report`); default: hashed here.
    geometry : Geometry, optional
        Where the shape channels are (``--geometry``): sets the report's
        ``input.mode_shape_nodes``, ``mode_shape_directions`` and ``mode_shape_xyz``.
        Without it, a UFF input's own nodes (datasets 15/2411) place the shape channels
        when they are inputs (reciprocity: the reader places only the outputs).
    options : TimeOptions, optional
        What the user says about a file of samples (:func:`time_options`).

    Returns
    -------
    RunOutcome

    Raises
    ------
    InputError
        If the input cannot be read or identified, the report cannot be checked against
        the baseline (shapes on other channels), or a report cannot be written.
    """
    data = read_input(path, options, settings, progress)  # imports the pipeline meanwhile
    from automodal.io.report import build_report
    from automodal.pipeline import identify

    result = identify(data, settings, progress=progress)
    report = build_report(result, data, input_path=path, sha256=sha256)
    if geometry is None and report.input.mode_shape_xyz is None:
        geometry = _own_nodes(path, data)
    if geometry is not None:
        from automodal.io.geometry import apply_to_report

        apply_to_report(report, geometry)
    check = None
    if baseline is not None:
        from automodal.app.monitoring import attach_monitoring

        try:
            check = attach_monitoring(report, baseline, baseline_path or "", thresholds)
        except ValueError as exc:
            raise InputError(
                f"cannot be checked against {baseline_path or 'the baseline'}: {exc}",
                os.fspath(path),
            ) from None
    if outputs:
        tell(progress, "writing")
    written = save_all(outputs, report, result)
    return RunOutcome(report=report, result=result, check=check, written=written)
