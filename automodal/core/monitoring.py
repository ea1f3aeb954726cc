"""Monitoring: today's modes against a baseline's, and modes tracked over time.

Pure functions on the modes of two identifications (no I/O). :func:`compare` matches the
physical modes of a new run to those of a baseline run by frequency and mode shape (a
Hungarian assignment on a cost that adds the relative frequency distance to ``1 - MAC``)
and flags a baseline mode

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
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

__all__ = [
    "DATE_KEYS",
    "History",
    "ModeCheck",
    "ModeTable",
    "MonitoringResult",
    "Thresholds",
    "build_history",
    "compare",
    "compare_reports",
    "mode_table",
    "report_time",
]

DATE_KEYS = ("test_date", "date", "datetime", "timestamp")
"""Keys of a report's ``input.attributes`` read as the test's date (ISO 8601), in order."""

_INADMISSIBLE = 1e6
"""Cost of a pair outside the matching gate (never chosen over an admissible one)."""


@dataclass(frozen=True)
class Thresholds:
    """When a mode counts as changed, and when two modes are the same mode.

    Attributes
    ----------
    k_sigma : float
        A frequency may move by ``k_sigma`` combined bootstrap standard deviations.
    min_relative_shift : float
        ... and always by at least this fraction of the baseline frequency (0.0025 = 0.25 %).
    min_mac : float
        A matched mode whose shape has a MAC below this with the baseline's is flagged.
    match_max_relative_shift : float
        Two modes further apart than this fraction of the baseline frequency are never
        matched (the baseline mode is then missing).
    match_min_mac : float
        Two modes whose shapes have a MAC below this are never matched.
    frequency_weight : float
        Relative frequency distance that costs as much as a MAC of 0 in the assignment
        (cost = ``|df| / f / frequency_weight + 1 - MAC``).
    """

    k_sigma: float = 5.0
    min_relative_shift: float = 0.0025
    min_mac: float = 0.95
    match_max_relative_shift: float = 0.15
    match_min_mac: float = 0.5
    frequency_weight: float = 0.05

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"threshold {name} must be finite and >= 0, got {value!r}")
        if self.frequency_weight <= 0:
            raise ValueError("threshold frequency_weight must be > 0")

    def to_dict(self) -> dict[str, float]:
        """Plain-JSON form."""
        return {k: float(v) for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, values: Mapping[str, Any] | None) -> Thresholds:
        """Thresholds from :meth:`to_dict` output (unknown keys are ignored)."""
        names = cls.__dataclass_fields__
        return cls(**{k: float(v) for k, v in (values or {}).items() if k in names})


@dataclass
class ModeTable:
    """The modes of one identification, as arrays (one entry per mode).

    Attributes
    ----------
    ids : ndarray of int
        Mode ids of the report.
    frequency_hz, frequency_std_hz : ndarray of float
        Central frequency and bootstrap standard deviation (NaN when unknown).
    frequency_ci95_hz : ndarray, shape (n, 2)
        Bootstrap 95 % interval of the frequency.
    damping_ratio, damping_std : ndarray of float
        Central damping ratio and bootstrap standard deviation.
    damping_ci95 : ndarray, shape (n, 2)
        Bootstrap 95 % interval of the damping ratio.
    physical : ndarray of bool
        The tool's decision.
    shapes : ndarray, shape (n, n_channels), complex
        Mode shapes (NaN where unknown; ``n_channels`` may be 0).
    cluster : ndarray of int
        Cluster of each mode; the members of a near-repeated cluster share it.
    """

    ids: np.ndarray
    frequency_hz: np.ndarray
    frequency_std_hz: np.ndarray
    frequency_ci95_hz: np.ndarray
    damping_ratio: np.ndarray
    damping_std: np.ndarray
    damping_ci95: np.ndarray
    physical: np.ndarray
    shapes: np.ndarray
    cluster: np.ndarray

    @property
    def n_modes(self) -> int:
        """Number of modes."""
        return int(self.ids.size)

    def subset(self, index: np.ndarray) -> ModeTable:
        """The modes at ``index`` (an integer or boolean index)."""
        return ModeTable(**{name: getattr(self, name)[index] for name in self.__dataclass_fields__})


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

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form (non-finite numbers as ``None``)."""
        return {k: _plain(v) for k, v in asdict(self).items()}


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

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form: ``flagged``, ``n_flagged``, ``thresholds`` and ``modes``."""
        return {
            "flagged": bool(self.flagged),
            "n_flagged": len(self.flagged_entries),
            "thresholds": self.thresholds.to_dict(),
            "modes": [e.to_dict() for e in self.entries],
        }


# ------------------------------------------------------------------------------ reading dicts


def mode_table(modes: Sequence[Mapping[str, Any]]) -> ModeTable:
    """The ``modes`` list of a report (``spec/report.md``) as a :class:`ModeTable`.

    Parameters
    ----------
    modes : sequence of dict
        Report mode entries; ``null`` numbers become NaN, a missing ``cluster`` gives each
        mode its own, a missing or ragged ``mode_shape`` gives shapes of NaN.

    Returns
    -------
    ModeTable
    """
    n = len(modes)

    def numbers(key: str) -> np.ndarray:
        return np.array([_number(m.get(key)) for m in modes], dtype=float)

    def pairs(key: str) -> np.ndarray:
        out = np.full((n, 2), np.nan)
        for i, m in enumerate(modes):
            value = m.get(key)
            if isinstance(value, (list, tuple)) and len(value) == 2:
                out[i] = [_number(value[0]), _number(value[1])]
        return out

    shapes = [_shape(m.get("mode_shape")) for m in modes]
    widths = {s.size for s in shapes}
    width = widths.pop() if len(widths) == 1 else 0
    shape_array = (
        np.vstack(shapes).astype(complex) if n and width else np.full((n, 0), np.nan, complex)
    )
    ids = np.array([int(m.get("id", i + 1)) for i, m in enumerate(modes)], dtype=int)
    clusters = [m.get("cluster") for m in modes]
    if any(c is None for c in clusters):
        cluster = -1 - np.arange(n)
    else:
        cluster = np.array(clusters, dtype=int)
    return ModeTable(
        ids=ids,
        frequency_hz=numbers("frequency_hz"),
        frequency_std_hz=numbers("frequency_std_hz"),
        frequency_ci95_hz=pairs("frequency_ci95_hz"),
        damping_ratio=numbers("damping_ratio"),
        damping_std=numbers("damping_std"),
        damping_ci95=pairs("damping_ci95"),
        physical=np.array([bool(m.get("physical")) for m in modes], dtype=bool),
        shapes=shape_array,
        cluster=cluster.reshape(n),
    )


def _number(value: Any) -> float:
    """A JSON number as float; ``None`` or anything else as NaN."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return math.nan
    return float(value)


def _shape(value: Any) -> np.ndarray:
    """A report's ``{"real": [...], "imag": [...]}`` as a complex vector (empty if absent)."""
    if not isinstance(value, Mapping):
        return np.zeros(0, complex)
    real = [_number(x) for x in value.get("real") or []]
    imag = [_number(x) for x in value.get("imag") or []]
    if len(real) != len(imag):
        return np.zeros(0, complex)
    return np.array(real, dtype=float) + 1j * np.array(imag, dtype=float)


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
    base = baseline.subset(baseline.physical & np.isfinite(baseline.frequency_hz))
    cur = current.subset(current.physical & np.isfinite(current.frequency_hz))
    base = base.subset(np.argsort(base.frequency_hz, kind="stable"))
    cur = cur.subset(np.argsort(cur.frequency_hz, kind="stable"))
    shapes_known = base.shapes.shape[1] > 0 and cur.shapes.shape[1] > 0
    if shapes_known and base.shapes.shape[1] != cur.shapes.shape[1]:
        raise ValueError(
            f"the mode shapes have {base.shapes.shape[1]} channels in the baseline and "
            f"{cur.shapes.shape[1]} today"
        )
    macs = cluster_mac(base, cur) if shapes_known else np.full((base.n_modes, cur.n_modes), np.nan)
    pairs = match(base.frequency_hz, cur.frequency_hz, macs, th)
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
    baseline: Mapping[str, Any], current: Mapping[str, Any], thresholds: Thresholds | None = None
) -> MonitoringResult:
    """:func:`compare` on two report dicts (their ``modes`` lists).

    Raises
    ------
    ValueError
        If the reports' mode shapes are on different channels (names or count).
    """
    names_b = _shape_channels(baseline)
    names_c = _shape_channels(current)
    if names_b and names_c and names_b != names_c:
        raise ValueError(
            "the mode shapes are on other channels than the baseline's "
            f"({', '.join(names_c[:4])}{'...' if len(names_c) > 4 else ''} against "
            f"{', '.join(names_b[:4])}{'...' if len(names_b) > 4 else ''})"
        )
    return compare(
        mode_table(baseline.get("modes") or []), mode_table(current.get("modes") or []), thresholds
    )


def _shape_channels(report: Mapping[str, Any]) -> list[str]:
    """The channel names of a report's mode shapes (empty when the report does not say)."""
    inp = report.get("input") or {}
    names = inp.get("mode_shape_channels") or inp.get("output_names") or []
    return [str(n) for n in names]


def cluster_mac(base: ModeTable, cur: ModeTable) -> np.ndarray:
    """MAC of each baseline shape with the span of each current mode's cluster.

    For a current mode alone in its cluster this is the ordinary MAC; for a member of a
    near-repeated cluster it is the share of the baseline shape that lies in the span of all
    members of that cluster (the members' own shapes wander inside a repeated root's span).

    Returns
    -------
    ndarray, shape (base.n_modes, cur.n_modes)
        In [0, 1]; NaN where a shape has non-finite entries or is zero.
    """
    out = np.full((base.n_modes, cur.n_modes), np.nan)
    a = base.shapes
    if a.shape[1] == 0 or cur.shapes.shape[1] != a.shape[1]:
        return out
    good_a = np.all(np.isfinite(a), axis=1) & (np.linalg.norm(a, axis=1) > 0)
    for c in np.unique(cur.cluster):
        members = np.flatnonzero(cur.cluster == c)
        span = cur.shapes[members]
        if not np.all(np.isfinite(span)) or not np.any(np.abs(span) > 0):
            continue
        q, _ = np.linalg.qr(span.T)
        proj = q.conj().T @ a[good_a].T
        share = np.sum(np.abs(proj) ** 2, axis=0) / np.sum(np.abs(a[good_a]) ** 2, axis=1)
        for j in members:
            out[good_a, j] = np.clip(share, 0.0, 1.0)
    return out


def match(
    f_base: np.ndarray, f_cur: np.ndarray, macs: np.ndarray, thresholds: Thresholds
) -> list[tuple[int, int]]:
    """Pairs ``(i, j)`` of baseline and current modes by a Hungarian assignment.

    The cost of a pair is ``|f_cur - f_base| / f_base / frequency_weight + 1 - MAC``
    (without the MAC term when it is NaN); pairs further apart than
    ``match_max_relative_shift`` or with a MAC below ``match_min_mac`` are not allowed.

    Returns
    -------
    list of (int, int)
        Allowed pairs of the minimum-cost assignment, by baseline index.
    """
    f_base = np.asarray(f_base, dtype=float)
    f_cur = np.asarray(f_cur, dtype=float)
    if f_base.size == 0 or f_cur.size == 0:
        return []
    rel = np.abs(f_cur[None, :] - f_base[:, None]) / np.abs(f_base[:, None])
    shape_cost = np.where(np.isnan(macs), 0.0, 1.0 - np.nan_to_num(macs))
    cost = rel / thresholds.frequency_weight + shape_cost
    allowed = rel <= thresholds.match_max_relative_shift
    allowed &= np.isnan(macs) | (np.nan_to_num(macs) >= thresholds.match_min_mac)
    cost = np.where(allowed, cost, _INADMISSIBLE)
    from scipy.optimize import linear_sum_assignment  # imported here: it is slow to load

    rows, cols = linear_sum_assignment(cost)
    return [(int(i), int(j)) for i, j in zip(rows, cols) if allowed[i, j]]


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
    label = f"mode {int(base.ids[i])} ({fb:.4g} Hz in the baseline)"
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
    )


def _missing_entry(base: ModeTable, i: int, cur_all: ModeTable, th: Thresholds) -> ModeCheck:
    """A baseline mode with no physical partner; names a non-physical cluster near it."""
    fb = float(base.frequency_hz[i])
    message = f"mode {int(base.ids[i])} ({fb:.4g} Hz in the baseline): missing"
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
        message=f"mode {int(cur.ids[j])} ({fc:.4g} Hz): new, not in the baseline",
    )


def _plain(value: Any) -> Any:
    """JSON-safe copy: numpy scalars to Python, non-finite floats to ``None``."""
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    return value


# ------------------------------------------------------------------------------ history


@dataclass
class History:
    """The baseline's physical modes tracked over a series of reports.

    ``T`` reports (sorted by time) and ``M`` tracked modes (the baseline's physical modes,
    by frequency). Values of a mode missing at a time are NaN.

    Attributes
    ----------
    times : list of str
        ISO 8601 time of each report (test date, else the report's creation).
    time_sources : list of str
        ``"test_date"`` (from ``input.attributes``) or ``"created"``, per report.
    labels : list of str
        Where each report came from (its path).
    baseline_label : str
        Where the baseline came from.
    mode_ids : ndarray of int, shape (M,)
        The baseline's ids of the tracked modes.
    baseline_frequency_hz, baseline_damping_ratio : ndarray, shape (M,)
    frequency_hz, frequency_std_hz, damping_ratio, damping_std, mac : ndarray, shape (T, M)
    frequency_ci95_hz, damping_ci95 : ndarray, shape (T, M, 2)
    mode_flagged : ndarray of bool, shape (T, M)
        The mode's check raised the alarm (moved, changed shape or missing).
    missing : ndarray of bool, shape (T, M)
    flagged : ndarray of bool, shape (T,)
        Any mode of the report flagged.
    n_new : ndarray of int, shape (T,)
        Physical modes of the report with no baseline partner.
    thresholds : Thresholds
    """

    times: list[str]
    time_sources: list[str]
    labels: list[str]
    baseline_label: str
    mode_ids: np.ndarray
    baseline_frequency_hz: np.ndarray
    baseline_damping_ratio: np.ndarray
    frequency_hz: np.ndarray
    frequency_std_hz: np.ndarray
    frequency_ci95_hz: np.ndarray
    damping_ratio: np.ndarray
    damping_std: np.ndarray
    damping_ci95: np.ndarray
    mac: np.ndarray
    mode_flagged: np.ndarray
    missing: np.ndarray
    flagged: np.ndarray
    n_new: np.ndarray
    thresholds: Thresholds = field(default_factory=Thresholds)

    @property
    def n_times(self) -> int:
        """Number of reports."""
        return len(self.times)

    @property
    def n_modes(self) -> int:
        """Number of tracked modes."""
        return int(self.mode_ids.size)


def report_time(report: Mapping[str, Any]) -> tuple[str, str]:
    """When a report's test was made: ``(iso_time, source)``.

    The first of :data:`DATE_KEYS` in ``input.attributes`` that parses as ISO 8601 wins
    (source ``"test_date"``); otherwise the report's ``created`` (source ``"created"``).
    Times without a zone are taken as UTC; the result is UTC with a ``Z``.

    Raises
    ------
    ValueError
        If neither gives a time.
    """
    attributes = (report.get("input") or {}).get("attributes") or {}
    for key in DATE_KEYS:
        parsed = _parse_time(attributes.get(key))
        if parsed is not None:
            return parsed, "test_date"
    parsed = _parse_time(report.get("created"))
    if parsed is None:
        raise ValueError("the report has neither a test date nor a valid 'created' time")
    return parsed, "created"


def _parse_time(value: Any) -> str | None:
    """An ISO 8601 text as UTC ``YYYY-MM-DDTHH:MM:SSZ``, or ``None``."""
    import datetime as dt

    if not isinstance(value, str) or not value.strip():
        return None
    text = value.strip()
    if text.endswith(("Z", "z")):
        text = text[:-1] + "+00:00"
    try:
        t = dt.datetime.fromisoformat(text)
    except ValueError:
        return None
    if t.tzinfo is None:
        t = t.replace(tzinfo=dt.timezone.utc)
    return t.astimezone(dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


def build_history(
    reports: Sequence[Mapping[str, Any]],
    labels: Sequence[str],
    baseline: Mapping[str, Any],
    baseline_label: str,
    thresholds: Thresholds | None = None,
) -> History:
    """Track the baseline's physical modes through a series of reports.

    Parameters
    ----------
    reports : sequence of dict
        Report dicts, in any order (they are sorted by :func:`report_time`, then label).
    labels : sequence of str
        Where each report came from.
    baseline : dict
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
            when, source = report_time(report)
        except ValueError as exc:
            raise ValueError(f"{label}: {exc}") from None
        stamped.append((when, str(label), source, report))
    stamped.sort(key=lambda s: (s[0], s[1]))
    base = mode_table(baseline.get("modes") or [])
    base = base.subset(base.physical & np.isfinite(base.frequency_hz))
    base = base.subset(np.argsort(base.frequency_hz, kind="stable"))
    column = {int(k): m for m, k in enumerate(base.ids)}
    T, M = len(stamped), base.n_modes
    h = History(
        times=[s[0] for s in stamped],
        time_sources=[s[2] for s in stamped],
        labels=[s[1] for s in stamped],
        baseline_label=str(baseline_label),
        mode_ids=base.ids.copy(),
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
        try:
            result = compare_reports(baseline, report, th)
        except ValueError as exc:
            raise ValueError(f"{label}: {exc}") from None
        cur = mode_table(report.get("modes") or [])
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
