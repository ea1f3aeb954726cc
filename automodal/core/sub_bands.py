"""Sub-bands: a wide band with many resonances identified piece by piece.

One model of a whole band needs about two states per resonance in it, and a subspace
identification of order ``n`` over ``N`` lines costs about ``N n^2`` per bootstrap replicate
(the projection) and ``n^3`` (the eigenvalues): a 10 000-line hammer FRF with about 30
resonances took minutes as one model of 256 states. Split into ``K`` sub-bands with a
``K``-th of the resonances each, the orders fall about ``K`` times and so does each
sub-band's line count: the work falls about ``K^2`` times. A band is split only when the
reference model the order scan chose would cost more than :data:`WORK_LIMIT` per replicate,
into the fewest sub-bands that bring the sum of their work under it.

The cuts are placed at the deepest valley of the mean magnitude between two neighbouring
resonance peaks, so that no resonance is cut. Each sub-band is analysed over its core
(the lines between its cuts) plus one resonance beyond each cut: a mode near a cut is fitted
with its neighbour in the model rather than in the residual. A mode belongs to the sub-band
whose core holds its frequency; the modes found in the overlaps are the neighbours' and are
dropped there.

Pure functions on arrays: the pipeline (:func:`automodal.pipeline.identify`) runs one
identification per sub-band and merges them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from automodal.core.magnitude import log_magnitude, mean_magnitude
from automodal.core.order import excessive_order, first_stage, lines_needed, peak_lines
from automodal.core.subspace import block_rows as default_block_rows
from automodal.core.subspace import replicate_work

__all__ = [
    "WORK_LIMIT", "SubBand", "plan_sub_bands", "replicate_work", "split_pays", "sub_band_count",
]

WORK_LIMIT = 2e8
"""Largest estimated work of one bootstrap replicate (multiply-adds of its projection,
:func:`replicate_work`) before a band is split. A replicate of the LADISK hammer FRF as one
model (10 000 lines, 256 states, one output: 2.6e9) took 0.66 s, 100 of them 66 s; at 2e8
the 100 replicates take about 5 s. Most of the family's test systems stay whole (44 of 48
files of seed 252; the four dense grids with reference orders of 160-200 are split):
splitting adds sub-band edges, where noise modes can pass for physical, so a model that is
cheap enough is identified whole."""


def sub_band_count(work: float, limit: float | None = None) -> int:
    """Fewest sub-bands ``K`` whose summed work ``work / K^2`` is at most ``limit`` (default
    :data:`WORK_LIMIT`; 1 when ``work`` already is)."""
    limit = WORK_LIMIT if limit is None else float(limit)
    if not work > limit:
        return 1
    return int(np.ceil(np.sqrt(work / limit)))


def split_pays(
    n_lines: int, ny: int, nu: int, n0: int, reference: int, block_rows: int,
    factor: float, n_bands: int,
) -> bool:
    """Whether ``n_bands`` sub-bands are predicted to cost less than the whole band.

    Each sub-band holds about a ``n_bands``-th of the lines and of the modes: its ``n0`` is
    that share of the band's (even, at least 2), its reference
    :func:`automodal.core.order.excessive_order` of it with ``factor`` (at most the
    band's), and its block rows fall with its reference in proportion (at least the
    default's). The sum of their replicates' work (:func:`replicate_work`) must be below
    the whole band's (the overlaps of one resonance beyond each cut are not counted: a
    slightly optimistic estimate). Where the band's reference is at its floor,
    ``n0 + 20`` for an ``n0`` the noise sets, and its block rows come from few directions
    above the noise rather than from its order, the sub-bands' models are no smaller:
    splitting only repeats the scans and the bootstraps for the same work (a file of H1
    noise alone, 35 x 3 outputs and inputs on 6000 lines: 4 sub-bands of 22 states on 15
    block rows each, 13.9 s).
    """
    K = int(n_bands)
    if K < 2:
        return False
    whole = replicate_work(n_lines, ny, nu, reference, block_rows)
    share = max(2, 2 * int(np.ceil(n0 / (2.0 * K))))
    ref_k = min(int(reference), excessive_order(share, int(reference), factor))
    q_k = max(default_block_rows(ref_k, ny), int(np.ceil(block_rows * ref_k / reference)))
    return K * replicate_work(int(np.ceil(n_lines / K)), ny, nu, ref_k, q_k) < whole


@dataclass(frozen=True)
class SubBand:
    """One sub-band of a split band.

    Attributes
    ----------
    core_hz : (float, float)
        Frequencies whose modes belong to this sub-band: ``lo <= f < hi`` (the last
        sub-band's ``hi`` included).
    analysed_hz : (float, float)
        Lines the sub-band's identification uses: the core and one resonance beyond each cut.
    n_peaks : int
        Resonances in the core: peaks of the magnitude, or the modes a model saw there
        (see :func:`plan_sub_bands`).
    """

    core_hz: tuple[float, float]
    analysed_hz: tuple[float, float]
    n_peaks: int

    def holds(self, frequency_hz: np.ndarray, last: bool) -> np.ndarray:
        """Whether each frequency lies in the core (``last``: the upper edge included)."""
        f = np.asarray(frequency_hz, dtype=float)
        lo, hi = self.core_hz
        return (f >= lo) & ((f <= hi) if last else (f < hi))


def plan_sub_bands(
    frequency_hz: np.ndarray, H: np.ndarray, n_bands: int, modes_hz: np.ndarray | None = None,
    variance: np.ndarray | None = None,
) -> list[SubBand]:
    """Split a band into ``n_bands`` sub-bands with as many resonances each.

    Parameters
    ----------
    frequency_hz : ndarray, shape (N,)
        Increasing lines of the band.
    H : ndarray, shape (N, ny, nu)
        The FRF over them (channels scaled alike, so that each counts in the mean
        magnitude).
    n_bands : int
        Sub-bands wanted (:func:`sub_band_count`).
    modes_hz : ndarray, optional
        Frequencies of the modes a model of the band sees (the order scan's largest model,
        :func:`automodal.core.stabilization.stable_frequencies`). Used instead of the
        magnitude's peaks when they are more: where modes overlap, one peak stands for
        several modes (an 8 x 10 grid, 40 outputs: 11 peaks for the 13 modes below
        15.5 Hz, and 11 for the 67 above), and sub-bands of equal peak counts are far from
        equal work. Not with fewer than two peaks (a band finely resolved, or with one
        resonance above the noise): the band then stays whole.
    variance : ndarray, shape (N, ny, nu), optional
        Noise variance of ``H``'s entries: a peak then counts only when it stands above the
        noise (:func:`automodal.core.order.peak_lines`). Without it, the wiggles where noise
        dominates count as resonances: in an accelerance measured with H1 (coherence
        0.4-0.6 below 5 Hz), 39 of the 54 "peaks" lay below the first mode (7.1 Hz), and
        the first sub-band, which held none of the 38 modes, took 24 of the file's 28 s;
        with the noise, 16 peaks, one of them below 7 Hz.

    Returns
    -------
    list of SubBand
        Fewer sub-bands when there are fewer resonances than ``n_bands``, or when so many
        would leave a sub-band too few lines for its order scan
        (:func:`automodal.core.order.lines_needed` of its first stage) or one that analyses
        the whole band again; one over the whole band when no split is possible.
    """
    f = np.asarray(frequency_hz, dtype=float)
    markers = peak_lines(H, variance=variance)
    if modes_hz is not None and markers.size >= 2:
        # not on the model's word alone: where the magnitude shows fewer than two peaks (a
        # band so finely resolved that its resonances are wider than the peak window: a
        # 9-DOF chain over 51 201 lines showed none) the cuts had no valley to trust, and
        # its order came from the lines rather than the modes (6 sub-bands took 20 s where
        # the whole band took 5.3 s)
        lines = np.unique(np.clip(np.searchsorted(f, np.asarray(modes_hz, dtype=float)),
                                  0, f.size - 1))
        if lines.size > markers.size:
            markers = lines
    span = (float(f[0]), float(f[-1]))
    _, ny, nu = H.shape
    logm = log_magnitude(mean_magnitude(H), 1e-12)
    for k in range(min(int(n_bands), markers.size), 1, -1):
        bands = _split(f, logm, markers, k)
        if all(_lines(f, b.analysed_hz) >= lines_needed(first_stage(b.n_peaks), ny, nu)
               and b.analysed_hz != span for b in bands):
            return bands
    return [SubBand(span, span, int(markers.size))]


def _split(f: np.ndarray, logm: np.ndarray, markers: np.ndarray, k: int) -> list[SubBand]:
    """``k`` sub-bands of consecutive resonances (``markers``: their lines), cut at the
    valleys between groups.

    Each cut lies at the deepest valley between two neighbouring resonances within a
    quarter of a group of the even split, so that a cut falls where the magnitude is lowest
    rather than between two modes of one overlapping pair.
    """
    m = markers.size

    def valley(i: int) -> int:
        """The line of least magnitude between resonance ``i`` and resonance ``i + 1``."""
        a, b = int(markers[i]), int(markers[i + 1])
        return a + int(np.argmin(logm[a : b + 1]))

    starts = [0]
    for nominal in (int(round(j * m / k)) for j in range(1, k)):
        reach = max(0, (m // k) // 4)
        lo, hi = max(starts[-1] + 1, nominal - reach), min(m - 1, nominal + reach)
        lo = min(lo, hi)
        starts.append(min(range(lo, hi + 1), key=lambda i: logm[valley(i - 1)]))
    n = f.size
    bands = []
    for first, end in zip(starts, starts[1:] + [m]):
        last = end - 1
        lo = 0 if first == 0 else valley(first - 1)
        hi = n - 1 if last == m - 1 else valley(last)
        a_lo = 0 if first < 2 else valley(first - 2)
        a_hi = n - 1 if last + 2 > m - 1 else valley(last + 1)
        bands.append(SubBand((float(f[lo]), float(f[hi])), (float(f[a_lo]), float(f[a_hi])),
                             int(end - first)))
    return bands


def _lines(f: np.ndarray, band: tuple[float, float]) -> int:
    """Lines of ``f`` within ``band`` (edges included)."""
    return int(np.count_nonzero((f >= band[0]) & (f <= band[1])))
