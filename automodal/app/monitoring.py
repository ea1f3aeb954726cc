"""Monitoring: today's modes against a baseline's, and modes tracked over time.

The application side of monitoring: reports (:class:`~automodal.report_model.Report`) in,
verdicts, messages, monitoring blocks and histories out (only :func:`history_of_files`
reads files). The numerical matching is :mod:`automodal.core.matching`. :func:`compare`
matches the physical modes of a new run to those of a baseline run by frequency and mode
shape (a Hungarian assignment on a cost that adds the relative frequency distance to
``1 - MAC``) and flags a baseline mode

* whose frequency moved by more than ``max(k_sigma * s, min_relative_shift * f_baseline)``,
  with ``s = sqrt(s_baseline^2 + s_today^2)`` the two bootstrap standard deviations combined;
* whose shape changed: MAC below ``min_mac``;
* that has no match among today's physical modes (it disappeared).

A physical mode of today with no baseline partner is listed as ``new`` but not flagged (a
newly excited or newly resolved mode is not by itself a change of the structure).

The default thresholds (:class:`Thresholds`) were chosen on simulated re-measurements: each
structure identified once as the baseline and again from 8 new noise realizations of the
same test, 20 bootstrap replicates each. Seven systems: 3- and 4-DOF chains at 1 % and 3 %
noise (300-400 lines, one input), a 6-DOF chain at 5 % noise (1000 lines), a 3x3 grid
(9 sensors, 2 inputs, 2 %) and a 3x4 grid with non-proportional damping seen as accelerance
by 7 sensors and 2 inputs (2 %); 328 matched mode pairs in all:

* ``|df| / s`` (s the combined bootstrap std): median 0.46, 99th percentile 2.1, largest 2.7
  (with 100 replicates: 0.38, 1.9, 2.5), so the bootstrap spread, although conditional on
  one noise realization, did not under-state the spread between re-measurements here;
* ``|df| / f``: median 5e-5, 99th percentile 4e-4, largest 7.4e-4 (0.074 %);
* MAC: smallest 0.9949; no baseline mode went unmatched (one new mode appeared).

``k_sigma = 5`` is 1.9 times the largest ``|df| / s`` seen and the floor of 0.25 % is 3.4
times the largest relative shift: no false alarm in the 56 re-measurements. The same seven
systems with one spring 10 % softer (4 noise realizations each) moved their most affected
mode by 0.63-2.98 % and all 28 runs were flagged; their MACs stayed above 0.990, so the
shape check (``min_mac = 0.95``) is for larger changes of shape than a softer spring makes.
Real structures also move with temperature and mass (often around 1 %): raise
``min_relative_shift`` for them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from automodal.core.matching import ModeTable, cluster_mac, match
from automodal.io.json_safe import json_safe
from automodal.report_model import MonitoringBlock, Report
from automodal.tracking import History, Thresholds

__all__ = [
    "History",
    "ModeCheck",
    "MonitoringResult",
    "Thresholds",
    "attach_monitoring",
    "baseline_identity",
    "build_history",
    "compare",
    "compare_reports",
    "history_of_files",
]


@dataclass
class ModeCheck:
    """The verdict on one mode of the baseline (or one new mode of today).

    Attributes
    ----------
    status : {"ok", "changed", "missing", "new"}
        ``changed``: matched but moved or changed shape; ``missing``: a baseline mode with
        no physical partner today; ``new``: a physical mode of today with no baseline partner.
    flagged : bool
        Whether this entry raises the alarm (``changed`` and ``missing`` do).
    reasons : list of str
        Among ``"frequency"``, ``"shape"``, ``"missing"``.
    baseline_id, id : int or None
        Mode ids in the baseline and in today's report.
    baseline_mode_number, mode_number : int or None
        Mode numbers (``mode_number`` of the reports: the physical modes 1, 2, ... by
        frequency) in the baseline and today; messages name a mode by its baseline number.
    baseline_frequency_hz, frequency_hz : float or None
        Central frequencies.
    shift_hz, relative_shift : float or None
        ``frequency_hz - baseline_frequency_hz`` and that over the baseline frequency.
    combined_std_hz : float or None
        ``sqrt(std_baseline^2 + std_today^2)`` (unknown spreads count as 0).
    allowed_shift_hz : float or None
        ``max(k_sigma * combined_std_hz, min_relative_shift * baseline_frequency_hz)``.
    mac : float or None
        MAC of today's shape with the baseline's (against the span of today's cluster for
        near-repeated modes); ``None`` when a shape is unknown.
    baseline_damping_ratio, damping_ratio : float or None
        Central damping ratios (reported, not checked: damping scatters too much).
    message : str
        One readable line.
    """

    status: str
    flagged: bool
    reasons: list[str]
    baseline_id: int | None
    id: int | None
    baseline_frequency_hz: float | None
    frequency_hz: float | None
    shift_hz: float | None = None
    relative_shift: float | None = None
    combined_std_hz: float | None = None
    allowed_shift_hz: float | None = None
    mac: float | None = None
    baseline_damping_ratio: float | None = None
    damping_ratio: float | None = None
    message: str = ""
    baseline_mode_number: int | None = None
    mode_number: int | None = None

    def to_dict(self, non_finite: list[str] | None = None, where: str = "") -> dict[str, Any]:
        """Plain-JSON form (non-finite numbers as ``None``, their fields added to
        ``non_finite``; see :func:`automodal.io.json_safe.json_safe`)."""
        return json_safe(asdict(self), where, non_finite)


@dataclass
class MonitoringResult:
    """Today's modes checked against a baseline.

    Attributes
    ----------
    entries : list of ModeCheck
        One per physical baseline mode (by baseline frequency), then one per new mode.
    flagged : bool
        Whether any entry is flagged.
    thresholds : Thresholds
        What was applied.
    """

    entries: list[ModeCheck]
    flagged: bool
    thresholds: Thresholds = field(default_factory=Thresholds)

    @property
    def flagged_entries(self) -> list[ModeCheck]:
        """The entries that raise the alarm."""
        return [e for e in self.entries if e.flagged]

    def to_dict(self, non_finite: list[str] | None = None, where: str = "") -> dict[str, Any]:
        """Plain-JSON form: ``flagged``, ``n_flagged``, ``thresholds`` and ``modes``
        (non-finite numbers as ``None``, their fields added to ``non_finite``)."""
        prefix = f"{where}." if where else ""
        return {
            "flagged": bool(self.flagged),
            "n_flagged": len(self.flagged_entries),
            "thresholds": self.thresholds.to_dict(),
            "modes": [e.to_dict(non_finite, f"{prefix}modes[{i}]")
                      for i, e in enumerate(self.entries)],
        }


# ------------------------------------------------------------------------------ comparing


def compare(
    baseline: ModeTable, current: ModeTable, thresholds: Thresholds | None = None
) -> MonitoringResult:
    """Check today's physical modes against the baseline's.

    Parameters
    ----------
    baseline, current : ModeTable
        The two identifications (all modes; only the physical ones are compared). Their
        shapes must have the same channels in the same order, or one of them none at all.
    thresholds : Thresholds, optional
        Defaults: :class:`Thresholds`.

    Returns
    -------
    MonitoringResult

    Raises
    ------
    ValueError
        If both have shapes but of different lengths.
    """
    th = thresholds or Thresholds()
    base = baseline.physical_by_frequency()
    cur = current.physical_by_frequency()
    shapes_known = base.shapes.shape[1] > 0 and cur.shapes.shape[1] > 0
    if shapes_known and base.shapes.shape[1] != cur.shapes.shape[1]:
        raise ValueError(
            f"the mode shapes have {base.shapes.shape[1]} channels in the baseline and "
            f"{cur.shapes.shape[1]} today"
        )
    macs = cluster_mac(base, cur) if shapes_known else np.full((base.n_modes, cur.n_modes), np.nan)
    pairs = match(base.frequency_hz, cur.frequency_hz, macs,
                  frequency_weight=th.frequency_weight,
                  max_relative_shift=th.match_max_relative_shift, min_mac=th.match_min_mac)
    partner = dict(pairs)
    entries = []
    for i in range(base.n_modes):
        j = partner.get(i)
        if j is None:
            entries.append(_missing_entry(base, i, current, th))
        else:
            entries.append(_matched_entry(base, i, cur, j, float(macs[i, j]), th))
    matched = set(partner.values())
    for j in range(cur.n_modes):
        if j not in matched:
            entries.append(_new_entry(cur, j))
    return MonitoringResult(entries, any(e.flagged for e in entries), th)


def compare_reports(
    baseline: Report, current: Report, thresholds: Thresholds | None = None
) -> MonitoringResult:
    """:func:`compare` on two reports (their modes).

    Raises
    ------
    ValueError
        If the reports' mode shapes are on different channels (names or count).
    """
    _check_channels(baseline, current)
    return compare(baseline.mode_table(), current.mode_table(), thresholds)


def _check_channels(baseline: Report, current: Report) -> None:
    """Refuse (``ValueError``) two reports whose mode shapes are on different channels."""
    names_b = baseline.shape_channels
    names_c = current.shape_channels
    if names_b and names_c and names_b != names_c:
        raise ValueError(
            "the mode shapes are on other channels than the baseline's "
            f"({', '.join(names_c[:4])}{'...' if len(names_c) > 4 else ''} against "
            f"{', '.join(names_b[:4])}{'...' if len(names_b) > 4 else ''})"
        )


def check_baseline(baseline: Report, path: str) -> Report:
    """``baseline``, refused (``InputError`` naming ``path``) when it has no physical mode
    with a frequency: every check against it would pass, whatever the structure did (a
    baseline made from a failed or pure-noise measurement)."""
    from automodal.errors import InputError

    if not baseline.physical_modes:
        raise InputError("the baseline report has no physical mode with a frequency, so no"
                         " change could be flagged against it: give a report of the healthy"
                         " structure", str(path))
    return baseline


def baseline_identity(baseline: Report, path: str) -> dict[str, Any]:
    """What names a baseline in a monitoring block: ``path``, ``created``, ``input_sha256``."""
    return {"path": str(path), "created": baseline.created, "input_sha256": baseline.input.sha256}


def attach_monitoring(
    report: Report, baseline: Report, baseline_path: str, thresholds: Thresholds | None = None
) -> MonitoringResult:
    """Check a report against a baseline report and set its ``monitoring`` block.

    Parameters
    ----------
    report : Report
        The new report (changed in place: ``monitoring``, and ``warnings`` when a number
        of the block is not finite).
    baseline : Report
        The baseline report.
    baseline_path : str
        Where the baseline was read from (recorded in the block).
    thresholds : Thresholds, optional

    Returns
    -------
    MonitoringResult

    Raises
    ------
    ValueError
        If the two reports' mode shapes are on different channels.

    Notes
    -----
    The block holds ``baseline`` (``path``, ``created``, ``input_sha256``), ``flagged``,
    ``n_flagged``, ``thresholds`` and ``modes``: one entry per physical baseline mode
    (``status`` ``ok``, ``changed`` or ``missing``) and one per new physical mode.
    """
    from automodal.io.json_safe import non_finite_warnings

    result = compare_reports(baseline, report, thresholds)
    non_finite: list[str] = []
    report.monitoring = MonitoringBlock.from_dict(
        {"baseline": baseline_identity(baseline, baseline_path),
         **result.to_dict(non_finite, "monitoring")})
    report.warnings.extend(non_finite_warnings(non_finite))
    return result


def _matched_entry(
    base: ModeTable, i: int, cur: ModeTable, j: int, mac: float, th: Thresholds
) -> ModeCheck:
    """The check of baseline mode ``i`` against its partner ``j``."""
    fb, fc = float(base.frequency_hz[i]), float(cur.frequency_hz[j])
    sb, sc = (np.nan_to_num(float(x)) for x in (base.frequency_std_hz[i], cur.frequency_std_hz[j]))
    combined = math.hypot(sb, sc)
    allowed = max(th.k_sigma * combined, th.min_relative_shift * abs(fb))
    shift = fc - fb
    reasons = []
    if abs(shift) > allowed:
        reasons.append("frequency")
    if math.isfinite(mac) and mac < th.min_mac:
        reasons.append("shape")
    label = f"mode {int(base.numbers[i])} ({fb:.4g} Hz in the baseline)"
    if reasons:
        parts = []
        if "frequency" in reasons:
            parts.append(
                f"frequency {fb:.4f} -> {fc:.4f} Hz ({100 * shift / fb:+.2f} %), beyond the "
                f"allowed ±{allowed:.4f} Hz"
            )
        if "shape" in reasons:
            parts.append(f"shape changed (MAC {mac:.3f} < {th.min_mac:g})")
        message = f"{label}: " + "; ".join(parts)
    else:
        message = f"{label}: ok, {fc:.4f} Hz ({100 * shift / fb:+.2f} %)"
    return ModeCheck(
        status="changed" if reasons else "ok",
        flagged=bool(reasons),
        reasons=reasons,
        baseline_id=int(base.ids[i]),
        id=int(cur.ids[j]),
        baseline_frequency_hz=fb,
        frequency_hz=fc,
        shift_hz=shift,
        relative_shift=shift / fb,
        combined_std_hz=combined,
        allowed_shift_hz=allowed,
        mac=mac if math.isfinite(mac) else None,
        baseline_damping_ratio=float(base.damping_ratio[i]),
        damping_ratio=float(cur.damping_ratio[j]),
        message=message,
        baseline_mode_number=int(base.numbers[i]),
        mode_number=int(cur.numbers[j]),
    )


def _missing_entry(base: ModeTable, i: int, cur_all: ModeTable, th: Thresholds) -> ModeCheck:
    """A baseline mode with no physical partner; names a non-physical cluster near it."""
    fb = float(base.frequency_hz[i])
    message = f"mode {int(base.numbers[i])} ({fb:.4g} Hz in the baseline): missing"
    near = np.flatnonzero(
        ~cur_all.physical
        & (np.abs(cur_all.frequency_hz - fb) <= th.match_max_relative_shift * abs(fb))
    )
    if near.size:
        k = near[np.argmin(np.abs(cur_all.frequency_hz[near] - fb))]
        message += (
            f" (a cluster not called physical is at {float(cur_all.frequency_hz[k]):.4f} Hz)"
        )
    return ModeCheck(
        status="missing",
        flagged=True,
        reasons=["missing"],
        baseline_id=int(base.ids[i]),
        id=None,
        baseline_frequency_hz=fb,
        frequency_hz=None,
        baseline_damping_ratio=float(base.damping_ratio[i]),
        message=message,
        baseline_mode_number=int(base.numbers[i]),
    )


def _new_entry(cur: ModeTable, j: int) -> ModeCheck:
    """A physical mode of today with no baseline partner (not flagged)."""
    fc = float(cur.frequency_hz[j])
    return ModeCheck(
        status="new",
        flagged=False,
        reasons=[],
        baseline_id=None,
        id=int(cur.ids[j]),
        baseline_frequency_hz=None,
        frequency_hz=fc,
        damping_ratio=float(cur.damping_ratio[j]),
        message=f"new mode at {fc:.4g} Hz (mode {int(cur.numbers[j])} of this test), "
                "not in the baseline",
        mode_number=int(cur.numbers[j]),
    )


# ------------------------------------------------------------------------------ history


def build_history(
    reports: Sequence[Report],
    labels: Sequence[str],
    baseline: Report,
    baseline_label: str,
    thresholds: Thresholds | None = None,
) -> History:
    """Track the baseline's physical modes through a series of reports.

    Parameters
    ----------
    reports : sequence of Report
        In any order (they are sorted by :meth:`Report.test_time`, then label).
    labels : sequence of str
        Where each report came from.
    baseline : Report
        The report whose physical modes are tracked and against which each report is
        checked with :func:`compare_reports`.
    baseline_label : str
    thresholds : Thresholds, optional

    Returns
    -------
    History

    Raises
    ------
    ValueError
        If a report has no time, or shapes on other channels than the baseline.
    """
    th = thresholds or Thresholds()
    if len(reports) != len(labels):
        raise ValueError("one label per report is needed")
    stamped = []
    for report, label in zip(reports, labels):
        try:
            when, source = report.test_time()
        except ValueError as exc:
            raise ValueError(f"{label}: {exc}") from None
        stamped.append((when, str(label), source, report))
    stamped.sort(key=lambda s: (s[0], s[1]))
    base_all = baseline.mode_table()
    base = base_all.physical_by_frequency()
    column = {int(k): m for m, k in enumerate(base.ids)}
    T, M = len(stamped), base.n_modes
    h = History(
        times=[s[0] for s in stamped],
        time_sources=[s[2] for s in stamped],
        labels=[s[1] for s in stamped],
        baseline_label=str(baseline_label),
        mode_ids=base.ids.copy(),
        mode_numbers=base.numbers.copy(),
        baseline_frequency_hz=base.frequency_hz.copy(),
        baseline_damping_ratio=base.damping_ratio.copy(),
        frequency_hz=np.full((T, M), np.nan),
        frequency_std_hz=np.full((T, M), np.nan),
        frequency_ci95_hz=np.full((T, M, 2), np.nan),
        damping_ratio=np.full((T, M), np.nan),
        damping_std=np.full((T, M), np.nan),
        damping_ci95=np.full((T, M, 2), np.nan),
        mac=np.full((T, M), np.nan),
        mode_flagged=np.zeros((T, M), bool),
        missing=np.zeros((T, M), bool),
        flagged=np.zeros(T, bool),
        n_new=np.zeros(T, int),
        thresholds=th,
    )
    for t, (_, label, _, report) in enumerate(stamped):
        cur = report.mode_table()
        try:  # compare_reports, with each report's table made once
            _check_channels(baseline, report)
            result = compare(base_all, cur, th)
        except ValueError as exc:
            raise ValueError(f"{label}: {exc}") from None
        row = {int(k): r for r, k in enumerate(cur.ids)}
        h.flagged[t] = result.flagged
        for e in result.entries:
            if e.status == "new":
                h.n_new[t] += 1
                continue
            m = column[int(e.baseline_id)]
            h.mode_flagged[t, m] = e.flagged
            h.missing[t, m] = e.status == "missing"
            if e.id is None:
                continue
            r = row[int(e.id)]
            h.frequency_hz[t, m] = cur.frequency_hz[r]
            h.frequency_std_hz[t, m] = cur.frequency_std_hz[r]
            h.frequency_ci95_hz[t, m] = cur.frequency_ci95_hz[r]
            h.damping_ratio[t, m] = cur.damping_ratio[r]
            h.damping_std[t, m] = cur.damping_std[r]
            h.damping_ci95[t, m] = cur.damping_ci95[r]
            h.mac[t, m] = np.nan if e.mac is None else e.mac
    return h


def history_of_files(
    files: Sequence[str], baseline_path: str | None = None, thresholds: Thresholds | None = None
) -> History:
    """Read report files and track the baseline's physical modes through them.

    Parameters
    ----------
    files : sequence of str
        Report files (JSON or HDF5).
    baseline_path : str, optional
        The baseline report; default the earliest of ``files`` (by
        :meth:`Report.test_time`, then name).
    thresholds : Thresholds, optional

    Returns
    -------
    History

    Raises
    ------
    InputError
        If a report cannot be read or is malformed, has no time, or has its shapes on
        other channels than the baseline (the message names the file).
    """
    from automodal.errors import InputError
    from automodal.io.report import load_report

    loaded = [load_report(f) for f in files]
    if baseline_path:
        where = Path(baseline_path).resolve()
        among = [r for r, f in zip(loaded, files) if Path(f).resolve() == where]
        baseline = among[0] if among else load_report(baseline_path)  # read each file once
        label = baseline_path
    else:
        times = []
        for report, path in zip(loaded, files):
            try:
                times.append(report.test_time()[0])
            except ValueError as exc:
                raise InputError(str(exc), path) from None
        first = min(range(len(files)), key=lambda i: (times[i], files[i]))
        baseline, label = loaded[first], files[first]
    check_baseline(baseline, label)
    try:
        return build_history(loaded, list(files), baseline, label, thresholds)
    except ValueError as exc:
        raise InputError(str(exc)) from None
