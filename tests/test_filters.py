"""The running filters of :mod:`automodal.core.filters` give ndimage's numbers."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from automodal.core import filters


@pytest.fixture(autouse=True)
def numpy_unless_large(monkeypatch):
    """The tests import ndimage, which would send every call to it: the NumPy path is
    taken as in a run where ndimage is not imported yet."""
    monkeypatch.setattr(filters, "_ndimage_loaded", lambda: False)


@pytest.mark.parametrize("n", [1, 2, 3, 7, 50, 301])
@pytest.mark.parametrize("size", [1, 2, 3, 4, 5, 11, 60, 88])
@pytest.mark.parametrize("mode", ["nearest", "mirror"])
def test_median_as_ndimage(n: int, size: int, mode: str) -> None:
    x = np.random.default_rng(n * 1000 + size).standard_normal(n)
    got = filters.running_median(x, size, mode=mode)
    np.testing.assert_array_equal(got, ndimage.median_filter(x, size=size, mode=mode))


@pytest.mark.parametrize("n", [1, 2, 9, 100])
@pytest.mark.parametrize("size", [1, 3, 4, 11, 30, 88])
def test_max_min_with_origins_as_ndimage(n: int, size: int) -> None:
    x = np.random.default_rng(n + 7 * size).standard_normal(n)
    for origin in {0, (size - 1) // 2, -(size // 2)}:
        np.testing.assert_array_equal(
            filters.running_max(x, size, origin=origin),
            ndimage.maximum_filter1d(x, size, mode="nearest", origin=origin))
        np.testing.assert_array_equal(
            filters.running_min(x, size, origin=origin),
            ndimage.minimum_filter1d(x, size, mode="nearest", origin=origin))


def test_large_work_goes_to_ndimage_with_the_same_numbers() -> None:
    x = np.random.default_rng(3).standard_normal(3000)
    size = filters.NUMPY_WORK_LIMIT // 3000 + 1
    np.testing.assert_array_equal(filters.running_median(x, size | 1, mode="mirror"),
                                  ndimage.median_filter(x, size=size | 1, mode="mirror"))


def test_bad_arguments_refused() -> None:
    with pytest.raises(ValueError):
        filters.running_max(np.zeros(5), 3, origin=5)
    with pytest.raises(ValueError):
        filters.running_median(np.zeros((2, 2)), 3)


def test_once_ndimage_is_imported_it_serves_every_call(monkeypatch) -> None:
    """Its import is paid then: a small median goes to it too, with the same numbers."""
    calls = []
    real = ndimage.median_filter

    def spy(*args, **kwargs):
        calls.append(args)
        return real(*args, **kwargs)

    monkeypatch.setattr(ndimage, "median_filter", spy)
    x = np.random.default_rng(5).standard_normal(200)
    small = filters.running_median(x, 11)
    assert not calls
    monkeypatch.setattr(filters, "_ndimage_loaded", lambda: True)
    np.testing.assert_array_equal(filters.running_median(x, 11), small)
    assert len(calls) == 1

