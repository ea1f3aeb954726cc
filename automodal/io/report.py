"""The identification report, version 1 (``docs/report.md``), as JSON or HDF5 files.

The content is the model :class:`~automodal.report_model.Report`; this module makes it for
a run (:func:`build_report`, which hashes the input file) and writes and reads files:
:func:`write_report` / :func:`save_report` write it (the suffix of the path chooses JSON or
HDF5) atomically, so that a failed run leaves no report at all; :func:`read_report` reads
either format back into the parsed dict and :func:`load_report` into a checked
:class:`~automodal.report_model.Report` (with the arrays an HDF5 report keeps for plotting,
:func:`read_report_arrays`); :func:`format_table` is the table the command line prints.

Every number of the content is a plain Python ``int`` or ``float`` (never a numpy scalar)
and is finite: a NaN or infinity becomes ``None`` (JSON ``null``) and adds a line to
``warnings`` naming the field (:mod:`automodal.io.json_safe`).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from automodal.errors import InputError
from automodal.frfdata import FRFData
from automodal.io.atomic import atomic_path, hdf5_in_memory
from automodal.report_model import (
    DATE_KEYS,
    FORMAT_NAME,
    FORMAT_VERSION,
    FRFArrays,
    Report,
    ReportArrays,
    ReportMode,
    as_floats,
    check_header,
    frequency_key,
    parse_time,
    utc_now,
)
from automodal.result import IdentifiedMode, PoleTable, Result

if TYPE_CHECKING:
    import h5py

    from automodal.core.stabilization import StabilizationPoles

__all__ = [
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "build_report",
    "file_sha256",
    "format_table",
    "load_report",
    "read_report",
    "read_report_arrays",
    "report_dict",
    "save_report",
    "write_report",
]

MAX_FRF_LINES = 2000
"""Most frequency lines of the FRFs kept in an HDF5 report (``/frf``); more are decimated."""

_JSON_SUFFIXES = (".json",)
_HDF5_SUFFIXES = (".h5", ".hdf5")
_HASH_CHUNK = 1 << 20

_MODE_FLOATS = (
    "frequency_hz",
    "frequency_std_hz",
    "damping_ratio",
    "damping_std",
    "physicalness",
    "mpc",
)
_MODE_INTS = ("id", "n_members", "cluster", "cluster_dim")
_MODE_PAIRS = ("frequency_ci95_hz", "damping_ci95")
_READ_ERRORS = (OSError, RuntimeError, KeyError, ValueError, TypeError)


class _Refused(Exception):
    """A problem with a report file; :func:`read_report` adds the path."""


# ------------------------------------------------------------------------------ content


def build_report(
    result: Result,
    data: FRFData,
    input_path: str | os.PathLike[str] | None = None,
    sha256: str | None = None,
) -> Report:
    """The report of one run (:meth:`Report.from_result`), its input file hashed.

    Parameters
    ----------
    result, data
        As for :meth:`Report.from_result`.
    input_path : str or path-like, optional
        The file ``data`` was read from; default ``data.source``. Its bytes are hashed
        (SHA-256) for ``input.sha256``, which is ``None`` when there is no file (or, with
        a warning, when it cannot be read).
    sha256 : str, optional
        The SHA-256 of that file when the caller has it already (a batch hashes each
        input before the run to skip up-to-date reports): the file is not hashed again.

    Returns
    -------
    Report
        Made now (``created``); its content, with the additions to ``docs/report.md``, is
        described at :meth:`Report.from_result`.
    """
    path = data.source if input_path is None else input_path
    warnings: list[str] = []
    sha = sha256
    if sha is None and path is not None:
        try:
            sha = file_sha256(path)
        except OSError as exc:
            reason = exc.strerror or type(exc).__name__
            warnings.append(
                f"input file {os.fspath(path)} could not be hashed ({reason}): sha256 is null"
            )
    warnings.extend(date_warnings(data.attributes))
    # ``created`` from this module's ``utc_now``, the clock the tests fix
    return Report.from_result(result, data, path, sha256=sha, created=utc_now(),
                              warnings=warnings)


def date_warnings(attributes: Mapping[str, Any]) -> list[str]:
    """A warning when the input states a test date (:data:`DATE_KEYS`) but none of them
    reads as ISO 8601: monitoring and ``automodal track`` then place the report at the
    time it was made, which they did without a word."""
    stated = [k for k in DATE_KEYS if attributes.get(k) is not None]
    if not stated or any(parse_time(attributes.get(k)) is not None for k in stated):
        return []
    key = stated[0]
    return [f"the input's {key} attribute {attributes[key]!r} is not an ISO 8601 date"
            " (2026-03-04T05:06:07): track and monitoring place this report at the time it"
            " was made"]


def report_dict(
    result: Result, data: FRFData, input_path: str | os.PathLike[str] | None = None
) -> dict:
    """``build_report(result, data, input_path).to_dict()``: the report's JSON content."""
    return build_report(result, data, input_path).to_dict()


def file_sha256(path: str | os.PathLike[str]) -> str:
    """SHA-256 of a file's bytes, read in chunks (as ``input.sha256`` records it).

    Raises
    ------
    OSError
        If the file cannot be read.
    """
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(_HASH_CHUNK), b""):
            digest.update(chunk)
    return digest.hexdigest()


# ------------------------------------------------------------------------------ writing


def write_report(
    path: str | os.PathLike[str],
    result: Result,
    data: FRFData,
    input_path: str | os.PathLike[str] | None = None,
    frf: FRFArrays | None = None,
) -> None:
    """Write the report of a run as JSON or HDF5, atomically.

    Parameters
    ----------
    path : str or path-like
        ``*.json`` for JSON (indented by 2), ``*.h5`` or ``*.hdf5`` for HDF5 (the
        layout of ``docs/report.md``, with every bootstrap pole under ``/poles``; the
        whole JSON report is kept in the root attribute ``report_json``).
    result, data, input_path
        As for :func:`build_report`.
    frf : (frequency, measured, synthesized), optional
        The analysed band's measured FRFs and those synthesized from the physical modes
        (``synthesized`` may be ``None``), kept under ``/frf`` of an HDF5 report for the
        plots (see :func:`save_report`); ignored for JSON.

    Raises
    ------
    InputError
        If the suffix of ``path`` is none of the above (nothing is written).

    Notes
    -----
    The file is written to a hidden temporary file beside ``path`` and renamed onto it at
    the end: when anything fails, ``path`` is left as it was and no temporary file stays.
    In HDF5, ``/input``, ``/summary`` and ``/trashbox`` hold their fields as attributes
    (``None`` left out, ``input.attributes`` as JSON text), ``/modes`` one dataset per
    field with one row per mode (a ``null`` number is NaN there), ``/poles`` every
    bootstrap pole, ``/frf`` the FRFs when given, and the root attribute ``warnings`` the
    warnings. To write the same report to several files use :func:`build_report` once and
    :func:`save_report` for each.
    """
    _format_of(path)
    save_report(path, build_report(result, data, input_path), result.poles, frf,
                result.stabilization)


def save_report(
    path: str | os.PathLike[str],
    report: Report | Mapping[str, Any],
    poles: PoleTable | None = None,
    frf: FRFArrays | None = None,
    stabilization: StabilizationPoles | None = None,
) -> None:
    """Write a report, as JSON or HDF5, atomically.

    Parameters
    ----------
    path : str or path-like
        ``*.json``, ``*.h5`` or ``*.hdf5``.
    report : Report or dict
        The report (a dict is JSON content written as it is, and must be finite: NaN is
        refused with ``ValueError``; for HDF5 it must be a valid report).
    poles : PoleTable, optional
        Every bootstrap pole, written under ``/poles`` of an HDF5 report (ignored for JSON).
    frf : (frequency, measured, synthesized), optional
        FRFs written under ``/frf`` of an HDF5 report (ignored for JSON): ``frequency``
        (Hz, shape ``(n,)``), ``measured`` and ``synthesized`` (complex, shape
        ``(n, n_outputs, n_inputs)``; ``synthesized`` may be ``None`` and is then left
        out). Lines outside the report's ``input.band_hz`` are dropped, and more than
        :data:`MAX_FRF_LINES` lines are decimated (every k-th line) to at most that many.
    stabilization : StabilizationPoles, optional
        The order scan's poles, written under ``/stabilization`` of an HDF5 report
        (ignored for JSON).

    Raises
    ------
    InputError
        For an unknown suffix, or a dict that is not a valid report for HDF5, before
        anything is written.
    ValueError
        If the arrays of ``frf`` do not fit together (nothing is written).
    """
    kind = _format_of(path)
    if kind == "json":
        content = report.to_dict() if isinstance(report, Report) else report
        with atomic_path(path) as tmp:
            _write_json(tmp, content)
        return
    model = Report.coerce(report)
    arrays = None if frf is None else _frf_for_report(model, frf)
    _write_hdf5(path, model, poles, arrays, stabilization)


def _format_of(path: str | os.PathLike[str]) -> str:
    """``"json"`` or ``"hdf5"`` from the suffix; :class:`InputError` otherwise."""
    suffix = Path(path).suffix.lower()
    if suffix in _JSON_SUFFIXES:
        return "json"
    if suffix in _HDF5_SUFFIXES:
        return "hdf5"
    raise InputError(
        f"unknown report suffix {suffix or '(none)'!r}: use .json, .h5 or .hdf5",
        os.fspath(path),
    )


def _write_json(path: Path, content: Mapping[str, Any]) -> None:
    """The report as indented UTF-8 JSON."""
    with open(path, "w", encoding="utf-8") as fh:
        json.dump(content, fh, indent=2, ensure_ascii=False, allow_nan=False)
        fh.write("\n")


def _frf_for_report(report: Report, frf: FRFArrays) -> dict[str, np.ndarray]:
    """The ``/frf`` datasets: checked, cut to the analysed band, decimated.

    Raises
    ------
    ValueError
        If the shapes of the arrays do not fit together.
    """
    frequency, measured, synthesized = frf
    freq = np.asarray(frequency, dtype=float).ravel()
    arrays = {"frequency": freq, "measured": np.asarray(measured, dtype=complex)}
    if synthesized is not None:
        arrays["synthesized"] = np.asarray(synthesized, dtype=complex)
    for name in ("measured", "synthesized"):
        if name in arrays and (arrays[name].ndim != 3 or arrays[name].shape[0] != freq.size):
            raise ValueError(
                f"frf: {name} has shape {arrays[name].shape}, expected ({freq.size}, ny, nu)"
            )
    if "synthesized" in arrays and arrays["synthesized"].shape != arrays["measured"].shape:
        raise ValueError(
            f"frf: synthesized has shape {arrays['synthesized'].shape}, measured"
            f" {arrays['measured'].shape}"
        )
    keep = np.ones(freq.size, dtype=bool)
    band = report.input.band_hz
    if len(band) == 2 and None not in band:
        keep = (freq >= band[0]) & (freq <= band[1])
    lines = np.flatnonzero(keep)
    step = max(1, math.ceil(lines.size / MAX_FRF_LINES))
    return {name: a[lines[::step]] for name, a in arrays.items()}


def _write_hdf5(
    path: str | os.PathLike[str],
    report: Report,
    poles: PoleTable | None,
    frf: dict[str, np.ndarray] | None = None,
    stabilization: StabilizationPoles | None = None,
) -> None:
    """The report in the HDF5 layout of ``docs/report.md``, plus its JSON text in
    ``report_json``, written atomically (built in memory: :func:`hdf5_in_memory`)."""
    import h5py

    content = report.to_dict()
    text = json.dumps(content, ensure_ascii=False, allow_nan=False)
    strings = h5py.string_dtype()
    with hdf5_in_memory(path) as f:
        for key, value in report.header.to_dict().items():
            f.attrs[key] = value
        f.attrs["settings"] = json.dumps(content["settings"], ensure_ascii=False)
        f.attrs["warnings"] = np.array(report.warnings, dtype=strings)
        f.attrs["report_json"] = text
        _write_attributes(f.create_group("input"), content["input"])
        _write_attributes(f.create_group("summary"), content["summary"])
        _write_attributes(f.create_group("trashbox"), content["trashbox"])
        _write_modes(f.create_group("modes"), report.modes, len(report.shape_channels))
        if poles is not None:
            _write_poles(f.create_group("poles"), poles)
        if stabilization is not None:
            _write_stabilization(f.create_group("stabilization"), stabilization)
        if frf is not None:
            group = f.create_group("frf")
            group.attrs["description"] = (
                "the analysed band's FRFs, measured and synthesized from the physical modes"
            )
            for name, values in frf.items():
                group.create_dataset(name, data=values)


def _write_attributes(group: h5py.Group, fields: dict[str, Any]) -> None:
    """Fields as HDF5 attributes: dicts as JSON text, ``None`` left out, null numbers NaN."""
    import h5py

    for key, value in fields.items():
        if value is None:
            continue
        if isinstance(value, dict):
            group.attrs[key] = json.dumps(value, ensure_ascii=False)
        elif isinstance(value, list) and all(isinstance(v, str) for v in value):
            group.attrs[key] = np.array(value, dtype=h5py.string_dtype())
        elif isinstance(value, list):
            group.attrs[key] = as_floats(value)
        else:
            group.attrs[key] = value


def _write_modes(group: h5py.Group, modes: list[ReportMode], n_outputs: int) -> None:
    """One dataset per mode field, one row per mode (``mode_shape`` complex)."""
    n = len(modes)
    for key in _MODE_FLOATS:
        group.create_dataset(key, data=as_floats([getattr(m, key) for m in modes]))
    for key in _MODE_INTS:
        if all(getattr(m, key) is not None for m in modes):
            group.create_dataset(key, data=np.array([getattr(m, key) for m in modes],
                                                    dtype=np.int64))
    for key in _MODE_PAIRS:
        pairs = as_floats([x for m in modes for x in getattr(m, key)])
        group.create_dataset(key, data=pairs.reshape(n, 2))
    group.create_dataset("physical", data=np.array([m.physical for m in modes], dtype=bool))
    group.create_dataset("mode_number", data=np.array([m.mode_number or 0 for m in modes],
                                                      dtype=np.int64))
    real = as_floats([x for m in modes for x in m.shape_real])
    imag = as_floats([x for m in modes for x in m.shape_imag])
    group.create_dataset("mode_shape", data=(real + 1j * imag).reshape(n, n_outputs))
    spread = as_floats([x for m in modes for x in m.mode_shape_std])
    group.create_dataset("mode_shape_std", data=spread.reshape(n, n_outputs))
    names = sorted({k for m in modes for k in m.features or {}})
    for name in names:
        values = [(m.features or {}).get(name) for m in modes]
        group.create_dataset(f"features/{name}", data=as_floats(values))


def _write_poles(group: h5py.Group, poles: PoleTable) -> None:
    """Every bootstrap pole: frequency, damping, cluster (-1 Trashbox), replicate."""
    group.attrs["description"] = "every bootstrap pole; cluster -1 is the Trashbox"
    group.create_dataset("frequency_hz", data=np.asarray(poles.frequency_hz, dtype=float))
    group.create_dataset("damping_ratio", data=np.asarray(poles.damping_ratio, dtype=float))
    group.create_dataset("cluster", data=np.asarray(poles.cluster, dtype=np.int64))
    group.create_dataset("replicate", data=np.asarray(poles.replicate, dtype=np.int64))


def _write_stabilization(group: h5py.Group, poles: StabilizationPoles) -> None:
    """The order scan's poles: order, frequency, damping and stability bits."""
    from automodal.core import stabilization as st

    group.attrs["description"] = (
        "poles of the order scan's models; stability bits against the previous order:"
        " 1 frequency, 2 damping, 4 shape (MAC)")
    group.attrs["frequency_tolerance"] = st.FREQUENCY_TOLERANCE
    group.attrs["damping_tolerance"] = st.DAMPING_TOLERANCE
    group.attrs["mac_tolerance"] = st.MAC_TOLERANCE
    group.create_dataset("order", data=np.asarray(poles.order, dtype=np.int64))
    group.create_dataset("frequency_hz", data=np.asarray(poles.frequency_hz, dtype=float))
    group.create_dataset("damping_ratio", data=np.asarray(poles.damping_ratio, dtype=float))
    group.create_dataset("stability", data=np.asarray(poles.stability, dtype=np.int64))


# ------------------------------------------------------------------------------ reading


def read_report(path: str | os.PathLike[str]) -> dict:
    """Read a report written by :func:`write_report` (JSON or HDF5).

    Parameters
    ----------
    path : str or path-like
        ``*.json`` or ``*.h5``/``*.hdf5``; with another suffix the content decides.

    Returns
    -------
    dict
        The parsed JSON content (an HDF5 report gives its ``report_json``); see
        :func:`load_report` for the checked model.

    Raises
    ------
    InputError
        If the file is missing, unreadable, not JSON or HDF5, not an automodal report, or of
        a newer report version. The message names the file.
    """
    with _reading(path) as p:
        report = _read_hdf5(p) if _is_hdf5_report(p) else _read_json(p)
        _check_header(report)
    return report


def load_report(path: str | os.PathLike[str], arrays: bool = False) -> Report:
    """Read a report file into a checked :class:`~automodal.report_model.Report`.

    Parameters
    ----------
    path : str or path-like
        As for :func:`read_report`.
    arrays : bool
        Also read the poles and FRFs an HDF5 report keeps (``Report.arrays``).

    Raises
    ------
    InputError
        As for :func:`read_report`, and for a report with a missing or malformed field
        (the message names the file and the field).
    """
    content = read_report(path)
    try:
        report = Report.from_dict(content)
    except InputError as exc:
        raise InputError(exc.problem, os.fspath(path)) from None
    if arrays:
        found = read_report_arrays(path)
        report.arrays = ReportArrays(poles=found["poles"] or None, frf=found["frf"] or None,
                                     stabilization=found["stabilization"] or None)
    return report


def read_report_arrays(path: str | os.PathLike[str]) -> dict[str, dict[str, np.ndarray]]:
    """The arrays a report keeps for plotting: every bootstrap pole and the FRFs.

    Parameters
    ----------
    path : str or path-like
        A report written by :func:`write_report` or :func:`save_report`.

    Returns
    -------
    dict
        ``"poles"``: ``frequency_hz``, ``damping_ratio``, ``cluster`` (``-1`` for the
        Trashbox) and ``replicate``, one entry per bootstrap pole; ``"frf"``:
        ``frequency`` (Hz), ``measured`` and, when it was written, ``synthesized``
        (complex, ``(n, n_outputs, n_inputs)``). Each is an empty dict when the report
        does not hold it (a JSON report holds neither).

    Raises
    ------
    InputError
        If the file is missing or unreadable, or an HDF5 file that is not an automodal
        report. The message names the file.
    """
    arrays: dict[str, dict[str, np.ndarray]] = {"poles": {}, "frf": {}, "stabilization": {}}
    with _reading(path) as p:
        if not _is_hdf5_report(p):
            return arrays
        import h5py

        if not h5py.is_hdf5(p):
            raise _Refused("not an HDF5 file (or truncated)")
        with h5py.File(p, "r") as f:
            fmt = f.attrs.get("format")
            if (fmt.decode("utf-8", "replace") if isinstance(fmt, bytes) else fmt) != FORMAT_NAME:
                raise _Refused(f"not an automodal report (format is not {FORMAT_NAME!r})")
            for name in arrays:
                group = f.get(name)
                if isinstance(group, h5py.Group):
                    arrays[name] = {
                        key: ds[()] for key, ds in group.items() if isinstance(ds, h5py.Dataset)
                    }
    return arrays


@contextmanager
def _reading(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Check that ``path`` is a file and turn read problems into :class:`InputError`."""
    source = os.fspath(path)
    p = Path(path)
    try:
        if not p.exists():
            raise _Refused("no such report file")
        if not p.is_file():
            raise _Refused("not a file")
        yield p
    except _Refused as exc:
        raise InputError(str(exc), source) from None
    except _READ_ERRORS as exc:
        msg = " ".join(str(exc).split()) or type(exc).__name__
        raise InputError(f"cannot read the report: {msg}", source) from exc


def _is_hdf5_report(path: Path) -> bool:
    """Whether to read ``path`` as HDF5: by suffix, or by content for other suffixes."""
    suffix = path.suffix.lower()
    if suffix in _HDF5_SUFFIXES:
        return True
    if suffix in _JSON_SUFFIXES:
        return False
    import h5py

    return bool(h5py.is_hdf5(path))


def _read_json(path: Path) -> Any:
    """Parse a JSON report."""
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError:
        raise _Refused("not a JSON report (not UTF-8 text)") from None
    except json.JSONDecodeError as exc:
        raise _Refused(f"not a valid JSON report ({exc})") from None


def _read_hdf5(path: Path) -> Any:
    """The report dict kept in an HDF5 report's ``report_json`` attribute."""
    import h5py  # only for HDF5 reports: a JSON run on a non-HDF5 input never loads it

    if not h5py.is_hdf5(path):
        raise _Refused("not an HDF5 file (or truncated)")
    with h5py.File(path, "r") as f:
        text = f.attrs.get("report_json")
    if text is None:
        raise _Refused("no 'report_json' attribute: not an automodal report")
    if isinstance(text, bytes):
        text = text.decode("utf-8")
    try:
        return json.loads(str(text))
    except json.JSONDecodeError as exc:
        raise _Refused(f"the 'report_json' attribute is not valid JSON ({exc})") from None


def _check_header(report: Any) -> None:
    """Refuse what is not an automodal report this version can read
    (:func:`~automodal.report_model.check_header`), or has no list of modes."""
    try:
        check_header(report)
    except InputError as exc:
        raise _Refused(exc.problem) from None
    if not isinstance(report.get("modes"), list):
        raise _Refused("the report has no list of modes")


# ------------------------------------------------------------------------------ the table


def format_table(result: Result, show_all: bool = False) -> str:
    """The modes of a run as an aligned text table with a one-line summary.

    Parameters
    ----------
    result : Result
    show_all : bool
        List every surviving cluster, the ones not called physical too (``mode`` ``-``,
        class ``not physical``); default only the physical modes.

    Returns
    -------
    str
        A header, one row per mode sorted by frequency (mode number, frequency in Hz ±
        std, damping in % ± std, physicalness, members, MPC; with ``show_all`` also the
        class), and a summary line; no trailing newline. A spread that cannot be
        estimated (a bootstrap cluster of one member) is ``n/a``, not ``± 0``.
    """
    header = ["mode", "frequency (Hz)", "damping (%)", "physicalness", "members", "MPC"]
    if show_all:
        header.insert(4, "class")
    modes = [m for m in sorted(result.modes, key=frequency_key) if show_all or m.physical]
    rows = [_table_row(m, show_all) for m in modes]
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    left = {4} if show_all else set()

    def line(cells: list[str]) -> str:
        parts = [
            c.ljust(w) if i in left else c.rjust(w) for i, (c, w) in enumerate(zip(cells, widths))
        ]
        return "  ".join(parts).rstrip()

    lines = [line(header), line(["-" * w for w in widths])]
    empty = "(no mode survived)" if not result.modes else "(no physical mode)"
    lines += [line(r) for r in rows] or [empty]
    lines.append(_summary_line(result, show_all))
    return "\n".join(lines)


def _table_row(mode: IdentifiedMode, show_all: bool) -> list[str]:
    """One row of :func:`format_table`."""
    known = mode.estimator != "bootstrap" or mode.n_members > 1

    def value(x: float, std: float, scale: float, digits: int) -> str:
        spread = (f"{scale * std:.{digits}f}" if known and math.isfinite(std)
                  else "n/a".rjust(digits + 2))
        return f"{scale * x:.{digits}f} ± {spread}"

    row = [
        str(mode.mode_number) if mode.mode_number is not None else "-",
        value(mode.frequency_hz, mode.frequency_std_hz, 1.0, 4),
        value(mode.damping_ratio, mode.damping_std, 100.0, 3),
        f"{mode.physicalness:.2f}",
        str(mode.n_members),
        f"{mode.mpc:.3f}",
    ]
    if show_all:
        row.insert(4, "physical" if mode.physical else "not physical")
    return row


def _summary_line(result: Result, show_all: bool = True) -> str:
    """``6 physical modes; 10 other clusters not shown (--all); 812 poles in the
    Trashbox; ...``."""
    n_bootstrap = result.settings.get("n_bootstrap")
    n_physical = len(result.physical_modes)
    n_other = len(result.modes) - n_physical
    parts = [f"{n_physical} physical mode{'s' if n_physical != 1 else ''}"]
    if n_other:
        others = f"{n_other} other cluster{'s' if n_other != 1 else ''}"
        parts.append(f"{others} not physical" if show_all else f"{others} not shown (--all)")
    parts.append(f"{result.trashbox_members} poles in the Trashbox")
    if n_bootstrap is not None:
        parts.append(f"{n_bootstrap} bootstrap replicates")
    parts.append(f"runtime {result.runtime_s:.1f} s")
    return "; ".join(parts)
