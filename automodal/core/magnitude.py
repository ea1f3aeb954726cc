"""The log magnitude of an FRF averaged over channels, and its roughness.

Shared by the data checks (:mod:`automodal.core.checks`: resonances, peaks on the band's
edges) and the order scan (:func:`automodal.core.order.count_peaks`), which judge peaks on
the same natural-log scale against the same noise measure.
"""

from __future__ import annotations

import numpy as np


def roughness(logm: np.ndarray) -> float:
    """Line-to-line roughness of a log magnitude: the median absolute second difference,
    scaled to a standard deviation of white noise (``1.4826 / sqrt(6)``); 0 for fewer
    than three lines."""
    if logm.size <= 2:
        return 0.0
    return 1.4826 * float(np.median(np.abs(np.diff(logm, 2)))) / np.sqrt(6.0)


def peak_threshold(rough: float) -> float:
    """The rise on the natural-log scale that makes a peak stand out: ``max(0.5, 6 s)``."""
    return max(0.5, 6.0 * rough)


def mean_magnitude(H: np.ndarray, channel_scales: np.ndarray | None = None) -> np.ndarray:
    """Mean over channels of ``|H|`` per line, each output divided by its scale first
    when ``channel_scales`` (shape ``(ny,)``) is given."""
    mag = np.abs(H)
    if channel_scales is not None:
        mag = mag / channel_scales[None, :, None]
    return np.mean(mag, axis=(1, 2))


def log_magnitude(mag: np.ndarray, floor_ratio: float = 1e-12) -> np.ndarray:
    """Natural log of ``mag``, values below ``floor_ratio`` times the largest raised to it
    (no log of 0; ``mag`` must have a positive value)."""
    return np.log(np.maximum(mag, np.max(mag) * floor_ratio))


def mean_log_magnitude(
    H: np.ndarray, channel_scales: np.ndarray | None = None, floor_ratio: float = 1e-12
) -> tuple[np.ndarray, float]:
    """Natural log of the mean over channels of ``|H|``, and its :func:`roughness`.

    Parameters
    ----------
    H : ndarray, shape (N, ny, nu)
        FRF, not all zero.
    channel_scales : ndarray, shape (ny,), optional
        Each output is divided by its scale first (e.g. its RMS, so that every channel
        counts alike).
    floor_ratio : float
        See :func:`log_magnitude`.

    Returns
    -------
    logm : ndarray, shape (N,)
    roughness : float
    """
    logm = log_magnitude(mean_magnitude(H, channel_scales), floor_ratio)
    return logm, roughness(logm)
