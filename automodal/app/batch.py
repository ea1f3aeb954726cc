"""Batch runs: the identification over a folder or a glob, one report per input.

:func:`run_batch` identifies every input file into an output folder, in parallel (joblib
worker processes, each file's own bootstrap then in one process), or on an existing Dask
distributed cluster. A file that cannot be read or identified is recorded with the one-line
reason and skipped; the batch goes on. ``summary.json`` and ``summary.csv`` in the output
folder list every file (written atomically). A file whose report is already there, made from
the same input bytes (SHA-256) with the same settings (and the same baseline check), is not
identified again unless ``force``.

With a baseline report, every file's report gets a ``monitoring`` block
(:func:`automodal.app.monitoring.attach_monitoring`). Each file goes through
:func:`automodal.app.run.run_file`, the same path as ``automodal identify`` on one file.

No command line here: :mod:`automodal.cli.identify_cmd` is the thin layer over it.
"""

from __future__ import annotations

import csv
import glob
import io
import json
import os
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

from automodal import __version__
from automodal.app.monitoring import baseline_identity
from automodal.app.run import check_jobs, is_batch_input, run_file
from automodal.errors import InputError
from automodal.io.atomic import atomic_path
from automodal.io.json_safe import json_safe
from automodal.io.readers import READERS, reader_suffix
from automodal.io.tabular import holds_number_rows
from automodal.report_model import Report, utc_now
from automodal.settings import Settings
from automodal.tracking import Thresholds

__all__ = [
    "REPORT_FORMATS",
    "SUMMARY_CSV",
    "SUMMARY_FORMAT",
    "SUMMARY_JSON",
    "BatchResult",
    "FileOutcome",
    "expand_inputs",
    "is_batch_input",
    "process_file",
    "report_stems",
    "run_batch",
]

SUMMARY_JSON = "summary.json"
"""Name of the JSON summary in the output folder."""

SUMMARY_CSV = "summary.csv"
"""Name of the CSV summary in the output folder."""

SUMMARY_FORMAT = "automodal-batch-summary"
"""Value of the summary's ``format`` key."""

REPORT_FORMATS = {"json": (".json",), "h5": (".h5",), "both": (".json", ".h5")}
"""Report suffixes written per input for each ``formats`` choice."""

CSV_COLUMNS = (
    "file", "time", "test_date", "status", "n_physical", "frequencies_hz", "monitoring",
    "runtime_s", "error",
)
"""Columns of ``summary.csv`` (frequencies of the physical modes joined by spaces)."""

STATUSES = ("ok", "flagged", "failed", "skipped")
"""``ok``: identified; ``flagged``: identified and the baseline check raised the alarm;
``failed``: no report (see ``error``); ``skipped``: an up-to-date report was already there."""


@dataclass
class FileOutcome:
    """What happened to one input of a batch.

    Attributes
    ----------
    file : str
        The input, as found.
    status : str
        One of :data:`STATUSES`.
    time : str
        When its report was made (UTC, ISO 8601), or when it failed.
    test_date : str or None
        The test's date from the input's attributes, when it has one.
    reports : list of str
        The report files (empty when failed).
    n_physical : int or None
        Physical modes found.
    frequencies_hz : list of float
        Their frequencies.
    monitoring : str or None
        ``"pass"`` or ``"flagged"`` with a baseline, else ``None``.
    flagged_modes : list of str
        One readable line per flagged mode.
    error : str or None
        Why it failed, in one line.
    runtime_s : float
        Wall time spent on this file.
    """

    file: str
    status: str
    time: str
    test_date: str | None = None
    reports: list[str] = field(default_factory=list)
    n_physical: int | None = None
    frequencies_hz: list[float] = field(default_factory=list)
    monitoring: str | None = None
    flagged_modes: list[str] = field(default_factory=list)
    error: str | None = None
    runtime_s: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form (see :func:`automodal.io.json_safe.json_safe`)."""
        return json_safe(asdict(self))


@dataclass
class BatchResult:
    """The outcome of :func:`run_batch`.

    Attributes
    ----------
    outcomes : list of FileOutcome
        One per input, in input order.
    summary_json, summary_csv : Path
        The summary files written.
    """

    outcomes: list[FileOutcome]
    summary_json: Path
    summary_csv: Path

    def count(self, status: str) -> int:
        """Inputs with this status."""
        return sum(1 for o in self.outcomes if o.status == status)

    @property
    def any_failed(self) -> bool:
        """Whether any input failed."""
        return self.count("failed") > 0

    @property
    def any_flagged(self) -> bool:
        """Whether any input identified in this run was flagged by the baseline check
        (skipped inputs raised their alarm when they were identified)."""
        return self.count("flagged") > 0


# ------------------------------------------------------------------------------ inputs


def expand_inputs(spec: str, exclude: str | os.PathLike[str] | None = None,
                  left_out: list[Path] | None = None) -> list[Path]:
    """The input files of a batch, sorted by name.

    Parameters
    ----------
    spec : str
        A folder (its files whose suffix has a reader, see
        :data:`automodal.io.readers.READERS`; not recursive, hidden files left out) or a
        glob pattern (every file it matches; ``**`` recurses). Text files (``.txt``,
        ``.csv``, ``.tsv``, also gzipped) in which no line is a row of numbers, such as a
        ``readme.txt`` beside the data, are no inputs
        (:func:`automodal.io.tabular.holds_number_rows`).
    exclude : path-like, optional
        A folder whose files are never inputs (the output folder).
    left_out : list of Path, optional
        Receives the text files left out for holding no numbers (to be said to the user).

    Returns
    -------
    list of Path

    Raises
    ------
    InputError
        If ``spec`` is neither an existing folder nor a glob pattern.
    """
    p = Path(spec)
    if p.is_dir():
        found = [f for f in p.iterdir() if reader_suffix(f) in READERS]
    elif glob.has_magic(spec):
        found = [Path(f) for f in glob.glob(spec, recursive=True)]
    else:
        raise InputError("no such folder, and not a glob pattern", spec)
    skip = Path(exclude).resolve() if exclude is not None else None
    files = [
        f for f in found
        if f.is_file() and not f.name.startswith(".")
        and (skip is None or f.resolve().parent != skip)
    ]
    prose = [f for f in files if READERS.get(reader_suffix(f)) == READERS[".txt"]
             and not holds_number_rows(f)]
    if left_out is not None:
        left_out.extend(sorted(prose, key=lambda f: str(f)))
    return sorted((f for f in files if f not in prose), key=lambda f: str(f))


def report_stems(files: Sequence[Path]) -> list[str | None]:
    """The report name (without suffix) of each input: its stem, or its whole name when
    another input has the same stem; ``None`` when even that collides (that input fails)."""
    stems = [f.stem for f in files]
    names = [f.stem if stems.count(f.stem) == 1 else f.name for f in files]
    seen: set[str] = set()
    out: list[str | None] = []
    for name in names:
        out.append(None if name in seen else name)
        seen.add(name)
    return out


# ------------------------------------------------------------------------------ one file


def process_file(
    path: str,
    stem: str | None,
    outdir: str,
    settings: Settings,
    suffixes: Sequence[str] = (".json",),
    baseline: Report | None = None,
    baseline_path: str | None = None,
    thresholds: Thresholds | None = None,
    force: bool = False,
) -> FileOutcome:
    """Identify one input of a batch into ``outdir``; never raises for a bad file.

    Parameters
    ----------
    path : str
        The input file.
    stem : str or None
        Report name without suffix (``None``: the name collides, the file fails).
    outdir : str
        The output folder.
    settings : Settings
        Settings of the identification (``jobs`` as the caller wants for this file).
    suffixes : sequence of str
        Report suffixes to write (``.json``, ``.h5``).
    baseline, baseline_path : Report and str, optional
        A baseline report to check against, and where it came from.
    thresholds : Thresholds, optional
    force : bool
        Identify even when up-to-date reports exist.

    Returns
    -------
    FileOutcome
    """
    t0 = time.perf_counter()
    try:
        if stem is None:
            raise InputError("another input has the same name: its report would be overwritten")
        targets = [Path(outdir) / f"{stem}{s}" for s in suffixes]
        sha = _input_sha256(path)
        if not force:
            old = _up_to_date(targets, sha, settings, baseline, baseline_path, thresholds)
            if old is not None:
                return _outcome(path, "skipped", old, targets, time.perf_counter() - t0)
        run = run_file(path, settings, targets, baseline, baseline_path, thresholds,
                       sha256=sha)
        return _outcome(path, "flagged" if run.flagged else "ok", run.report, targets,
                        time.perf_counter() - t0)
    except InputError as exc:
        reason = exc.problem if exc.path in (None, str(path)) else str(exc)
    except Exception as exc:  # noqa: BLE001 - one bad file must not stop the batch
        msg = " ".join(str(exc).split()) or type(exc).__name__
        reason = f"internal error: {type(exc).__name__}: {msg}"
    return FileOutcome(file=str(path), status="failed", time=utc_now(), error=reason,
                       runtime_s=time.perf_counter() - t0)


def _input_sha256(path: str) -> str:
    """SHA-256 of an input's bytes (as the report records it)."""
    from automodal.io.report import file_sha256

    try:
        return file_sha256(path)
    except OSError:
        p = Path(path)
        raise InputError("no such file" if not p.exists() else "cannot be read", path) from None


def _up_to_date(
    targets: Sequence[Path],
    sha: str,
    settings: Settings,
    baseline: Report | None,
    baseline_path: str | None,
    thresholds: Thresholds | None,
) -> Report | None:
    """The existing report when every target is there and was made from the same input
    with the same settings (and, with a baseline, checked against the same one with the
    same thresholds); else ``None``."""
    from automodal.io.report import load_report

    wanted = json_safe(settings.to_dict())
    first = None
    for target in targets:
        if not target.is_file():
            return None
        try:
            report = load_report(target)
        except InputError:
            return None
        if report.input.sha256 != sha:
            return None
        if not report.settings.records(wanted):
            return None
        if baseline is not None:
            block = report.monitoring
            if (block is None
                    or block.baseline != baseline_identity(baseline, baseline_path or "")
                    or block.thresholds != (thresholds or Thresholds()).to_dict()):
                return None
        first = first or report
    return first


def _outcome(
    path: str, status: str, report: Report, targets: Sequence[Path], runtime: float
) -> FileOutcome:
    """The outcome of an identified (or skipped) file, from its report."""
    physical = [m for m in report.modes if m.physical]
    block = report.monitoring
    return FileOutcome(
        file=str(path),
        status=status,
        time=report.created or utc_now(),
        test_date=report.test_date(),
        reports=[str(t) for t in targets],
        n_physical=len(physical),
        frequencies_hz=[m.frequency_hz for m in physical],
        monitoring=None if block is None else ("flagged" if block.flagged else "pass"),
        flagged_modes=[] if block is None else block.flagged_messages,
        runtime_s=round(runtime, 3),
    )


# ------------------------------------------------------------------------------ the batch


def run_batch(
    files: Sequence[str | os.PathLike[str]],
    outdir: str | os.PathLike[str],
    settings: Settings | None = None,
    formats: str = "json",
    baseline: Report | None = None,
    baseline_path: str | None = None,
    thresholds: Thresholds | None = None,
    force: bool = False,
    jobs: int | None = None,
    scheduler_address: str | None = None,
    progress: Callable[[FileOutcome], None] | None = None,
    spec: str | None = None,
) -> BatchResult:
    """Identify many files into ``outdir`` and write the summary.

    Parameters
    ----------
    files : sequence of path-like
        The inputs (see :func:`expand_inputs`).
    outdir : path-like
        The output folder (created when missing).
    settings : Settings, optional
        Settings of every identification; its ``jobs`` is ignored (see ``jobs``).
    formats : {"json", "h5", "both"}
        Report files per input: ``<stem>.json``, ``<stem>.h5`` or both.
    baseline, baseline_path : Report and str, optional
        Check every report against this baseline report.
    thresholds : Thresholds, optional
    force : bool
        Identify files whose up-to-date reports exist.
    jobs : int, optional
        Worker processes, >= 1 (default ``None``: all cores). With more than one file and more
        than one worker, files run in parallel and each file's bootstrap in one process; otherwise
        files run one after the other, each bootstrap with ``jobs`` processes.
    scheduler_address : str, optional
        Address of a running Dask distributed scheduler (``tcp://host:8786``): each file is a
        task on that cluster and ``jobs`` is not used (the ``dask`` extra is needed).
    progress : callable, optional
        Called with each :class:`FileOutcome`, in input order, as soon as it is known.
    spec : str, optional
        How the inputs were given (folder or glob), for the summary.

    Returns
    -------
    BatchResult

    Raises
    ------
    InputError
        For an unknown ``formats``, ``jobs`` below 1, an output folder that cannot be made, or a
        Dask scheduler that cannot be used.
    """
    if formats not in REPORT_FORMATS:
        raise InputError(f"unknown report format {formats!r}: use json, h5 or both")
    check_jobs(jobs)
    out = Path(outdir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"the output folder cannot be made ({exc.strerror})", str(out)) from None
    base_settings = settings or Settings()
    paths = [str(f) for f in files]
    stems = report_stems([Path(f) for f in paths])
    workers = min(len(paths), jobs or os.cpu_count() or 1)
    per_file = replace(base_settings, jobs=1 if workers > 1 or scheduler_address else jobs)
    common = dict(outdir=str(out), settings=per_file, suffixes=REPORT_FORMATS[formats],
                  baseline=baseline, baseline_path=baseline_path, thresholds=thresholds,
                  force=force)
    if scheduler_address:
        stream = _on_dask(scheduler_address, paths, stems, common)
    elif workers > 1:
        stream = _on_joblib(workers, paths, stems, common)
    else:
        stream = (process_file(p, s, **common) for p, s in zip(paths, stems))
    outcomes = []
    for outcome in stream:
        outcomes.append(outcome)
        if progress is not None:
            progress(outcome)
    summary = _summary(outcomes, spec, out, base_settings, formats, baseline, baseline_path,
                       thresholds)
    json_path, csv_path = out / SUMMARY_JSON, out / SUMMARY_CSV
    with atomic_path(json_path) as tmp:
        tmp.write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    with atomic_path(csv_path) as tmp:
        tmp.write_text(_csv_text(outcomes), encoding="utf-8")
    return BatchResult(outcomes, json_path, csv_path)


def _on_joblib(
    workers: int, paths: list[str], stems: list[str | None], common: dict[str, Any]
) -> Iterator[FileOutcome]:
    """Files in joblib worker processes, results in input order as they come."""
    from joblib import Parallel, delayed

    run = Parallel(n_jobs=workers, backend="loky", return_as="generator")
    yield from run(delayed(process_file)(p, s, **common) for p, s in zip(paths, stems))


def _on_dask(
    address: str, paths: list[str], stems: list[str | None], common: dict[str, Any]
) -> Iterator[FileOutcome]:
    """Files as tasks on an existing Dask distributed cluster, results in input order."""
    try:
        from dask.distributed import Client
    except ImportError:
        raise InputError(
            "--dask-scheduler needs Dask distributed: pip install 'automodal[dask]'"
        ) from None
    try:
        client = Client(address, timeout="10s", set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        msg = " ".join(str(exc).split()) or type(exc).__name__
        raise InputError(f"cannot reach the Dask scheduler at {address}: {msg}") from None
    try:
        # a worker runs in a folder of its own: relative paths would name files there (the
        # inputs not found, the reports written beside the worker), so the tasks get the
        # caller's absolute paths (os.path.abspath: links not resolved), and the outcomes
        # the paths as the caller gave them
        task = dict(common, outdir=os.path.abspath(common["outdir"]))
        futures = [client.submit(process_file, os.path.abspath(p), s, pure=False, **task)
                   for p, s in zip(paths, stems)]
        for p, future in zip(paths, futures):
            yield as_given(future.result(), p, common["outdir"])
    finally:
        client.close()




def as_given(outcome: FileOutcome, path: str, outdir: str) -> FileOutcome:
    """An outcome of a task given absolute paths, with the input and its reports named as
    the caller gave them (``path``, reports in ``outdir``)."""
    return replace(outcome, file=str(path),
                   reports=[str(Path(outdir) / Path(r).name) for r in outcome.reports])


def _summary(
    outcomes: list[FileOutcome],
    spec: str | None,
    outdir: Path,
    settings: Settings,
    formats: str,
    baseline: Report | None,
    baseline_path: str | None,
    thresholds: Thresholds | None,
) -> dict[str, Any]:
    """The content of ``summary.json`` (plain JSON, see :mod:`automodal.io.json_safe`)."""
    return json_safe({
        "format": SUMMARY_FORMAT,
        "version": 1,
        "automodal_version": __version__,
        "created": utc_now(),
        "input": spec,
        "outdir": str(outdir),
        "settings": settings.to_dict(),
        "report_formats": list(REPORT_FORMATS[formats]),
        "baseline": None if baseline is None else {
            **baseline_identity(baseline, baseline_path or ""),
            "thresholds": (thresholds or Thresholds()).to_dict(),
        },
        "counts": {"files": len(outcomes), **{s: sum(o.status == s for o in outcomes)
                                               for s in STATUSES}},
        "files": [o.to_dict() for o in outcomes],
    })


def _csv_text(outcomes: list[FileOutcome]) -> str:
    """``summary.csv``: one row per input, :data:`CSV_COLUMNS`."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for o in outcomes:
        writer.writerow([
            o.file, o.time, o.test_date or "", o.status,
            "" if o.n_physical is None else o.n_physical,
            " ".join(f"{f:.6g}" for f in o.frequencies_hz if f is not None),
            o.monitoring or "", f"{o.runtime_s:.3f}", o.error or "",
        ])
    return buffer.getvalue()
