"""Running median, maximum and minimum over a window of lines (1-D), as scipy.ndimage's.

The data checks, the order scan and the line weights of every run smooth or compare the
magnitude over a window of lines. :mod:`scipy.ndimage` does it, but importing it costs
30-90 ms. Here a window of a short array is taken in NumPy (a strided view of the padded
array, reduced along the window), and only when the work (lines x window) is large, so
that the import pays for itself (:data:`NUMPY_WORK_LIMIT`), or when ndimage is imported
already, are the ndimage filters used. Both give the same numbers
(``tests/test_filters.py`` checks them against ndimage).
"""

from __future__ import annotations

import sys
from collections.abc import Callable

import numpy as np

__all__ = ["running_max", "running_median", "running_min"]

NUMPY_WORK_LIMIT = 1 << 21
"""Largest ``lines x window`` done in NumPy while :mod:`scipy.ndimage` is not imported.

A NumPy median costs about 10 ns per number of its windows (37 ms for 6000 lines and a
601-line window), ndimage's 0.4 ms for the same, and importing ndimage 30-60 ms once
scipy.linalg is loaded. A run filters its band about three times at one size, so from
2 M numbers per call (60 ms in NumPy over three calls) the import pays; once imported,
ndimage serves every call. (At 4 M, a 6000-line file's three medians took 0.11 s in NumPy:
a tenth of its identification.)"""

_PAD_MODES = {"nearest": "edge", "mirror": "reflect"}
"""ndimage's boundary modes that are used here, as :func:`numpy.pad` names them."""


def _ndimage_loaded() -> bool:
    """Whether :mod:`scipy.ndimage` is imported already (its import then costs nothing)."""
    return "scipy.ndimage" in sys.modules


def running_median(x: np.ndarray, size: int, mode: str = "nearest") -> np.ndarray:
    """``scipy.ndimage.median_filter(x, size, mode=mode)`` of a 1-D array (for an even
    ``size`` the upper of the two middle values, as ndimage takes)."""

    def median(windows: np.ndarray) -> np.ndarray:
        return np.partition(windows, size // 2, axis=1)[:, size // 2]

    return _running(x, size, mode, 0, median, "median_filter")


def running_max(x: np.ndarray, size: int, mode: str = "nearest", origin: int = 0) -> np.ndarray:
    """``scipy.ndimage.maximum_filter1d(x, size, mode=mode, origin=origin)``."""
    return _running(x, size, mode, origin, lambda w: np.max(w, axis=1), "maximum_filter1d")


def running_min(x: np.ndarray, size: int, mode: str = "nearest", origin: int = 0) -> np.ndarray:
    """``scipy.ndimage.minimum_filter1d(x, size, mode=mode, origin=origin)``."""
    return _running(x, size, mode, origin, lambda w: np.min(w, axis=1), "minimum_filter1d")


def _running(
    x: np.ndarray,
    size: int,
    mode: str,
    origin: int,
    reduce: Callable[[np.ndarray], np.ndarray],
    ndimage_name: str,
) -> np.ndarray:
    """The window of each line (``size`` lines starting ``size // 2 + origin`` before it,
    the array extended at its ends by ``mode``) reduced by ``reduce``."""
    x = np.asarray(x, dtype=float)
    if x.ndim != 1 or size < 1 or mode not in _PAD_MODES:
        raise ValueError(f"a 1-D array, a size >= 1 and a mode of {sorted(_PAD_MODES)} needed")
    left = size // 2 + origin
    if not 0 <= left <= size - 1:
        raise ValueError(f"origin {origin} puts the window of size {size} off its line")
    if x.size == 0:
        return x.copy()
    # ndimage extends an array shorter than the window in its own way: left to it
    if (_ndimage_loaded() or x.size * size > NUMPY_WORK_LIMIT
            or (mode == "mirror" and size > x.size)):
        from scipy import ndimage

        if ndimage_name == "median_filter":
            return ndimage.median_filter(x, size=size, mode=mode)
        return getattr(ndimage, ndimage_name)(x, size, mode=mode, origin=origin)
    padded = np.pad(x, (left, size - 1 - left), mode=_PAD_MODES[mode])
    windows = np.lib.stride_tricks.sliding_window_view(padded, size)
    return reduce(windows)

