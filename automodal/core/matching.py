"""Matching the modes of two identifications: MAC on cluster spans and a Hungarian assignment.

Pure functions on arrays (no report dicts, no I/O): :class:`ModeTable` holds the modes of
one identification as arrays, :func:`cluster_mac` compares the shapes of two tables and
:func:`match` pairs their modes by frequency and MAC. The verdicts built on these (moved,
changed shape, missing) are in :mod:`automodal.app.monitoring`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["INADMISSIBLE", "ModeTable", "cluster_mac", "match", "mode_numbers"]

INADMISSIBLE = 1e6
"""Cost of a pair outside the matching gate (never chosen over an admissible one)."""



def mode_numbers(frequency_hz: np.ndarray, physical: np.ndarray) -> np.ndarray:
    """The numbers users see: the physical modes 1, 2, ... by frequency (non-finite
    frequencies last, ties in the given order), 0 for the others.

    Parameters
    ----------
    frequency_hz : ndarray, shape (n,)
    physical : ndarray of bool, shape (n,)

    Returns
    -------
    ndarray of int, shape (n,)
    """
    f = np.asarray(frequency_hz, dtype=float)
    numbers = np.zeros(f.size, dtype=int)
    order = np.argsort(np.where(np.isfinite(f), f, np.inf), kind="stable")
    chosen = order[np.asarray(physical, dtype=bool)[order]]
    numbers[chosen] = np.arange(1, chosen.size + 1)
    return numbers

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
    numbers : ndarray of int, optional
        Mode numbers: the physical modes 1, 2, ... by frequency, 0 for the others (what
        messages call a mode). Default: so numbered from ``physical`` and the frequencies.
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
    numbers: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.numbers is None:
            self.numbers = mode_numbers(self.frequency_hz, self.physical)

    @property
    def n_modes(self) -> int:
        """Number of modes."""
        return int(self.ids.size)

    def subset(self, index: np.ndarray) -> ModeTable:
        """The modes at ``index`` (an integer or boolean index)."""
        return ModeTable(**{name: getattr(self, name)[index] for name in self.__dataclass_fields__})

    def physical_by_frequency(self) -> ModeTable:
        """The physical modes with a finite frequency, sorted by frequency (stable)."""
        keep = self.subset(self.physical & np.isfinite(self.frequency_hz))
        return keep.subset(np.argsort(keep.frequency_hz, kind="stable"))


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
    f_base: np.ndarray,
    f_cur: np.ndarray,
    macs: np.ndarray,
    *,
    frequency_weight: float,
    max_relative_shift: float,
    min_mac: float,
) -> list[tuple[int, int]]:
    """Pairs ``(i, j)`` of baseline and current modes by a Hungarian assignment.

    Parameters
    ----------
    f_base, f_cur : ndarray
        Frequencies of the baseline's and the current modes.
    macs : ndarray, shape (len(f_base), len(f_cur))
        MAC of each pair (NaN when unknown), e.g. from :func:`cluster_mac`.
    frequency_weight : float
        Relative frequency distance that costs as much as a MAC of 0.
    max_relative_shift : float
        Pairs further apart than this fraction of the baseline frequency are not allowed.
    min_mac : float
        Pairs with a (known) MAC below this are not allowed.

    Returns
    -------
    list of (int, int)
        Allowed pairs of the minimum-cost assignment, by baseline index. The cost of a
        pair is ``|f_cur - f_base| / f_base / frequency_weight + 1 - MAC`` (without the MAC
        term when it is NaN).
    """
    f_base = np.asarray(f_base, dtype=float)
    f_cur = np.asarray(f_cur, dtype=float)
    if f_base.size == 0 or f_cur.size == 0:
        return []
    rel = np.abs(f_cur[None, :] - f_base[:, None]) / np.abs(f_base[:, None])
    shape_cost = np.where(np.isnan(macs), 0.0, 1.0 - np.nan_to_num(macs))
    cost = rel / frequency_weight + shape_cost
    allowed = rel <= max_relative_shift
    allowed &= np.isnan(macs) | (np.nan_to_num(macs) >= min_mac)
    cost = np.where(allowed, cost, INADMISSIBLE)
    from scipy.optimize import (
        linear_sum_assignment,  # imported here: it is slow to load
    )

    rows, cols = linear_sum_assignment(cost)
    return [(int(i), int(j)) for i, j in zip(rows, cols) if allowed[i, j]]
