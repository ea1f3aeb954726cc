"""The lines a band needs: thinning a band sampled far more finely than its resonances.

Every stage of an identification costs time in proportion to the lines (the projection,
each bootstrap replicate, the refinement), and memory too. A band of 200 000 lines with
three modes, each some 500 lines wide at half power, gives nothing for the extra lines but
precision: the poles are as well resolved by every tenth line. Such a band keeps every
``k``-th line (:func:`thinning_step`): towards :data:`THIN_ABOVE_LINES` lines, but never so
far that its narrowest resonance keeps fewer than :data:`LINES_PER_HALF_POWER_BAND` lines
across its half-power band. The lines kept are lines of the data, so a noise model of each
line holds as it did; the lines left out carried information, and the intervals are about
``sqrt(k)`` times wider than all the lines would give.

Pure functions on arrays: the pipeline (:func:`automodal.pipeline.prepare`) thins the band
and its noise model, and says so in a warning.
"""

from __future__ import annotations

import numpy as np

from automodal.core.filters import running_max
from automodal.core.magnitude import mean_magnitude

__all__ = [
    "LINES_PER_HALF_POWER_BAND",
    "PEAK_SIGMAS",
    "THIN_ABOVE_LINES",
    "narrowest_peak_lines",
    "thinning_step",
]

THIN_ABOVE_LINES = 20_000
"""Lines above which a band is thinned to the resolution its resonances need. A one-output
test of 2^20 lines with 3 modes (decimated to 200 000 lines, the most the identification
takes) took 17-22 s and 1.6 GB, and one of 2^22 lines 57 s and 2.7 GB (split into sub-bands
that the lines, not the modes, made costly). Tests measured for modal analysis (hammer and
shaker FRFs, and the FRFs automodal computes from time records) mostly have a few thousand
lines, the test family up to 6000: their analysis is unchanged. Finer ones are thinned only
as far as their resonances allow: the real roving-hammer beam (``docs/validation.md``, 47 873
lines in its 65-1000 Hz band) keeps every line, its narrowest peak being 2 lines wide."""

LINES_PER_HALF_POWER_BAND = 10
"""Lines a thinned band keeps across the half-power band of its narrowest resonance peak.
Modes down to 1.5 lines in their half-power band are identified (the test family's
"unresolved" limit), so a mode up to about 6 times narrower than the narrowest peak seen (a
weak one, under the noise or beside a neighbour) keeps what it needs."""

PEAK_SIGMAS = 10.0
"""A peak sets the resolution when its fall to half power (``1 - 1/sqrt 2`` of its height)
is this many standard deviations of the mean magnitude's noise. A maximum of the noise on
a resonance's flank crosses that level only by a dip of the noise: at 6 standard deviations
(:data:`automodal.core.order.PEAK_NOISE_SIGMAS`) such crossings came every few hundred
lines on a 200 000-line test whose noise floor was 1/21 of the flank; the largest and the
smallest of the ~200 lines searched differ by 10 standard deviations with a probability
near 1e-10. A real peak that fails this only keeps lines that thinning would drop."""


def narrowest_peak_lines(H: np.ndarray, variance: np.ndarray, reach: int) -> float:
    """Width in lines of the narrowest resonance peak that stands out of the noise.

    A peak is a line of the mean magnitude over the FRF entries that is the largest within
    :data:`LINES_PER_HALF_POWER_BAND` lines on either side, whose fall to half power is
    :data:`PEAK_SIGMAS` noise standard deviations (from ``variance``), and that does fall
    to half power within ``reach`` lines on one side at least. Its width is twice the
    distance to its nearer half-power point, and at most the distance to the nearest other
    peak: a pair of close resonances needs the lines between them.

    Parameters
    ----------
    H : ndarray, shape (N, ny, nu)
        FRF.
    variance : ndarray, shape (N, ny, nu)
        Its noise variance per line and entry.
    reach : int
        Widest width of interest, in lines (at least 1).

    Returns
    -------
    float
        The width, at most ``2 reach`` (``2 reach`` when the maxima that stand out of the
        noise are all wider); ``nan`` when none does (nothing says how fine the lines must
        be).
    """
    mag = mean_magnitude(H)
    n_entries = H.shape[1] * H.shape[2]
    # noise std of the mean of |H| over the entries: var(|h|) is at most var(h) / 2
    sigma = np.sqrt(0.5 * np.sum(variance, axis=(1, 2))) / n_entries
    window = 2 * LINES_PER_HALF_POWER_BAND + 1
    fall = (1.0 - 1.0 / np.sqrt(2.0)) * mag
    peaks = np.flatnonzero((mag >= running_max(mag, window)) & (fall > PEAK_SIGMAS * sigma))
    if peaks.size == 0:
        return float("nan")
    level = mag[peaks] / np.sqrt(2.0)
    offsets = np.arange(1, int(reach) + 1)
    near = np.full(peaks.size, float(reach))
    crossed = np.zeros(peaks.size, bool)
    for side in (-1, 1):
        at = peaks[:, None] + side * offsets[None, :]
        inside = (at >= 0) & (at < mag.size)
        below = inside & (mag[np.clip(at, 0, mag.size - 1)] < level[:, None])
        found = below.any(axis=1)
        near[found] = np.minimum(near[found], offsets[np.argmax(below[found], axis=1)])
        crossed |= found
    # a maximum that does not fall to half power within the reach is a resonance wider
    # than that, or the noise on a resonance's flank: neither asks for finer lines
    if not crossed.any():
        return 2.0 * float(reach)
    peaks, width = peaks[crossed], 2.0 * near[crossed]
    if peaks.size > 1:
        gaps = np.diff(peaks).astype(float)
        width = np.minimum(width, np.minimum(np.append(gaps, np.inf), np.append(np.inf, gaps)))
    return float(np.min(width))


def thinning_step(H: np.ndarray, variance: np.ndarray) -> tuple[int, float]:
    """Every how many lines a band is kept, and the width of its narrowest peak.

    Parameters
    ----------
    H : ndarray, shape (N, ny, nu)
        The band's FRF.
    variance : ndarray, shape (N, ny, nu)
        Its noise variance per line and entry.

    Returns
    -------
    k : int
        1 (every line) for at most :data:`THIN_ABOVE_LINES` lines, or when no peak stands
        out of the noise; else the step towards :data:`THIN_ABOVE_LINES` lines that keeps
        :data:`LINES_PER_HALF_POWER_BAND` lines across the narrowest peak
        (:func:`narrowest_peak_lines`).
    width : float
        That peak's width in lines (``nan`` when not measured).
    """
    n = H.shape[0]
    if n <= THIN_ABOVE_LINES:
        return 1, float("nan")
    most = int(np.ceil(n / THIN_ABOVE_LINES))
    width = narrowest_peak_lines(H, variance, most * LINES_PER_HALF_POWER_BAND)
    if not np.isfinite(width):
        return 1, width
    return max(1, min(most, int(width // LINES_PER_HALF_POWER_BAND))), width
