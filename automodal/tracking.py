"""Typed monitoring data: the thresholds of a monitoring check, and a tracked history.

Shared by the application layer (:mod:`automodal.app.monitoring`, which computes them) and
the I/O layer (:mod:`automodal.io.history`, which writes and reads histories), so that
neither depends on the other.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

__all__ = ["History", "Thresholds"]


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
    mode_numbers : ndarray of int, shape (M,)
        Their mode numbers in the baseline (1, 2, ...: what messages and figures call them).
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
    mode_numbers: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.mode_numbers is None:  # a history written before the numbers existed
            self.mode_numbers = np.arange(1, np.asarray(self.mode_ids).size + 1)

    @property
    def n_times(self) -> int:
        """Number of reports."""
        return len(self.times)

    @property
    def n_modes(self) -> int:
        """Number of tracked modes."""
        return int(self.mode_ids.size)
