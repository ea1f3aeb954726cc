"""Unit tests of :mod:`automodal.core.order` on synthetic misfit curves and an exact
two-mode SISO system."""

from __future__ import annotations

import numpy as np
import pytest

from automodal.core import bilinear, subspace
from automodal.core.order import (
    excessive_order,
    log_misfit,
    misfit_scan,
    order_at_floor,
    plateaued,
    still_falling,
)

ORDERS = np.arange(2, 42, 2)  # 2, 4, ..., 40: 20 orders


# ---------------------------------------------------------------------------------------
# log_misfit
# ---------------------------------------------------------------------------------------


def _frf() -> np.ndarray:
    rng = np.random.default_rng(0)
    return rng.normal(size=(30, 2, 3)) + 1j * rng.normal(size=(30, 2, 3))


def test_log_misfit_of_identical_frfs_is_zero():
    H = _frf()
    assert log_misfit(H, H) == 0.0


def test_log_misfit_factor_e_is_one_and_symmetric():
    H = _frf()
    assert log_misfit(np.e * H, H) == pytest.approx(1.0, rel=1e-12)
    assert log_misfit(H, np.e * H) == pytest.approx(1.0, rel=1e-12)  # not -1
    assert log_misfit(H / np.e, H) == pytest.approx(1.0, rel=1e-12)


def test_log_misfit_ignores_phase_and_common_scale():
    H = _frf()
    assert log_misfit(H * np.exp(0.7j), H) == pytest.approx(0.0, abs=1e-14)
    G = H * np.exp(0.1 * np.arange(30))[:, None, None]
    assert log_misfit(1e6 * G, 1e6 * H) == pytest.approx(log_misfit(G, H), rel=1e-12)


def test_log_misfit_mean_over_lines_and_channels():
    H = np.ones((4, 1, 2), dtype=complex)
    Hm = H.copy()
    Hm[0, 0, 0] = np.e  # one entry of 8 off by a factor e: mean 1/8
    assert log_misfit(Hm, H) == pytest.approx(1.0 / 8.0, rel=1e-12)


def test_log_misfit_skips_zeros():
    H = np.array([1.0, 0.0, 2.0, 5.0])
    Hm = np.array([np.e, 3.0, 0.0, 5.0])  # only entries 0 and 3 count: (1 + 0) / 2
    assert log_misfit(Hm, H) == pytest.approx(0.5, rel=1e-12)
    assert log_misfit(np.zeros(3), np.ones(3)) == float("inf")


# ---------------------------------------------------------------------------------------
# order_at_floor
# ---------------------------------------------------------------------------------------


def test_clean_drop_then_floor_gives_the_drop_order():
    rng = np.random.default_rng(1)
    misfit = np.where(ORDERS < 12, 3.0, 0.01 * (1 + 0.1 * rng.random(ORDERS.size)))
    assert order_at_floor(ORDERS, misfit) == 12


@pytest.mark.parametrize("drop", [4, 10, 22, 30])
def test_drop_position_is_found_exactly(drop):
    misfit = np.where(ORDERS < drop, 2.0 - 0.01 * ORDERS, 0.05)
    assert order_at_floor(ORDERS, misfit) == drop


def test_flat_noise_only_curve_gives_the_first_order():
    assert order_at_floor(ORDERS, np.full(ORDERS.size, 0.8)) == 2


def test_jittered_noise_only_curve_gives_its_first_deepest_dip():
    # best-so-far: 0.80, 0.80, 0.79, 0.79, 0.785, 0.785, ...: floor 0.785, top 0.80,
    # limit min(1.1775, 0.785 + 0.05 * 0.015) = 0.78575 -> the dip at n = 10
    misfit = np.full(ORDERS.size, 0.80)
    misfit[[1, 2, 4]] = [0.81, 0.79, 0.785]
    assert order_at_floor(ORDERS, misfit) == 10


def test_curve_that_keeps_falling():
    # MC(n) = 2^(-n/2): best-so-far = itself; upper half 2^-11 .. 2^-20, its median
    # (2^-15 + 2^-16) / 2 = 1.5 * 2^-16; limit min(1.5 * floor, floor + 0.05 (0.5 - floor))
    # = 2.25 * 2^-16; the first order at or below it: 2^-15 = 2 * 2^-16 at n = 30
    misfit = 2.0 ** (-ORDERS / 2.0)
    assert order_at_floor(ORDERS, misfit) == 30


def test_fraction_of_the_fall_matters_when_the_floor_is_high():
    # falls from 3.4 to a floor of 1.0: factor alone (1.5) would accept 1.4 at n = 10;
    # with 5 % of the fall (1 + 0.05 * 2.4 = 1.12) the order is 14 (1.1)
    misfit = np.r_[[3.4, 3.0, 2.5, 2.0, 1.4, 1.2, 1.1], np.full(13, 1.0)]
    assert order_at_floor(ORDERS, misfit) == 14
    assert order_at_floor(ORDERS, misfit, fraction=1.0) == 10


def test_limit_is_inclusive():
    # floor 1, top 3: limit = min(1.5, 1 + 0.05 * 2) = 1.1; an order at exactly 1.1 counts
    misfit = np.r_[[3.0, 2.0, 1.1], np.full(17, 1.0)]
    assert order_at_floor(ORDERS, misfit, fraction=0.05) == 6


def test_rising_again_after_the_minimum_uses_the_best_so_far():
    # the curve reaches 0.01 at 12 then rises to 0.5 (a truncated model fitting worse);
    # against the raw upper half (0.5) the answer would be far too early (n = 4)
    misfit = np.r_[[3.0, 1.0, 0.4, 0.1, 0.05], np.full(1, 0.01), np.full(14, 0.5)]
    assert order_at_floor(ORDERS, misfit) == 12


def test_non_finite_misfits_are_skipped():
    misfit = np.where(ORDERS < 12, 3.0, 0.01)
    misfit[[0, 7]] = np.inf
    misfit[9] = np.nan
    assert order_at_floor(ORDERS, misfit) == 12
    assert order_at_floor(ORDERS, np.full(ORDERS.size, np.inf)) == 2


def test_order_at_floor_returns_a_python_int():
    assert type(order_at_floor(ORDERS, np.where(ORDERS < 12, 3.0, 0.01))) is int


# ---------------------------------------------------------------------------------------
# excessive_order
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "n0,n_max,expected",
    [
        (4, 200, 24),  # max(12, 24): n0 + 20 wins
        (10, 200, 30),  # max(30, 30): both
        (12, 200, 36),  # max(36, 32): 3 n0 wins
        (11, 200, 32),  # max(33, 31) = 33, made even downwards
        (40, 100, 100),  # capped at n_max
        (40, 99, 98),  # capped, then even
        (0, 200, 20),
        (1, 1, 2),  # never below 2 (even when n_max is smaller)
    ],
)
def test_excessive_order(n0, n_max, expected):
    got = excessive_order(n0, n_max)
    assert got == expected
    assert got % 2 == 0


# ---------------------------------------------------------------------------------------
# still_falling and plateaued
# ---------------------------------------------------------------------------------------


def test_still_falling_on_typical_curves():
    assert still_falling(ORDERS, 3.0 - 0.05 * ORDERS)  # steady fall: a third of it left
    # a geometric fall is nearly over in absolute terms (2^-13 -> 2^-20 of a fall of 0.5)
    assert not still_falling(ORDERS, 2.0 ** (-ORDERS / 2.0))
    assert not still_falling(ORDERS, np.where(ORDERS < 12, 3.0, 0.01))
    assert not still_falling(ORDERS, np.full(ORDERS.size, 1.0))


def test_still_falling_share_is_strict():
    # orders 0, 3, 6, 9: last third starts after 6; best 9 -> 1, whole fall 8, fall in the
    # last third 2 -> 1 = 1 = 0.125 * 8
    orders = np.array([0, 3, 6, 9])
    misfit = np.array([9.0, 5.0, 2.0, 1.0])
    assert not still_falling(orders, misfit, share=0.125)
    assert still_falling(orders, misfit, share=0.12)


def test_still_falling_uses_the_best_so_far():
    # a rise at the end is not a fall, and a dip then recovery does not count twice
    orders = np.array([0, 3, 6, 9])
    assert not still_falling(orders, np.array([9.0, 5.0, 1.0, 4.0]))


def test_still_falling_needs_three_finite_orders():
    assert not still_falling(np.array([2, 4]), np.array([3.0, 1.0]))
    assert not still_falling(ORDERS, np.full(ORDERS.size, np.inf))


def test_plateaued_ten_percent_rule():
    orders = np.arange(2, 52, 2)  # 2 .. 50, patience 24: past = orders <= 26
    flat = np.r_[np.linspace(3, 1, 10), np.full(15, 1.0)]
    assert plateaued(orders, flat)  # no improvement over the last 24 states
    exactly = flat.copy()
    exactly[-1] = 0.9  # improved by exactly 10 %: not plateaued (needs > 0.9 min)
    assert not plateaued(orders, exactly)
    almost = flat.copy()
    almost[-1] = 0.91
    assert plateaued(orders, almost)


def test_plateaued_reads_misfits_at_rounding_level_as_the_floor():
    # noise-free data: which rounding-level misfit is smaller is the BLAS kernels' chance
    orders = np.array([2, 4, 6, 8])
    assert plateaued(orders, np.array([1.2, 1.3e-14, 7.2e-15, 3.7e-15]), patience=4)
    assert not plateaued(orders, np.array([1.2, 1e-3, 1e-4, 1e-5]), patience=4)
    # nor does a fall among rounding-level misfits count as still falling
    assert not still_falling(np.arange(2, 14, 2), np.array([3, 2, 1, 0.5, 0.2, 0.1]) * 1e-14)


def test_plateaued_needs_a_past_window():
    orders = np.arange(2, 22, 2)  # 2 .. 20: nothing is 24 states back
    assert not plateaued(orders, np.ones(orders.size))
    assert not plateaued(orders, np.ones(orders.size), patience=0)


# ---------------------------------------------------------------------------------------
# misfit_scan on an exact two-mode SISO system
# ---------------------------------------------------------------------------------------


def _two_mode_siso():
    """``H(s) = sum r/(s - l) + conj``: order 4 exactly (its bilinear image too)."""
    w = np.linspace(1.0, 40.0, 300)
    lam = np.array([-0.5 + 10.0j, -1.0 + 25.0j])
    res = np.array([-2.0j, 1.0 - 3.0j])
    s = 1j * w[:, None]
    H = (res / (s - lam) + res.conj() / (s - lam.conj())).sum(axis=1)[:, None, None]
    T = bilinear.default_scale(w[0], w[-1])
    return bilinear.to_unit_circle(w, T), H


def test_misfit_scan_drops_to_zero_at_the_true_order():
    z, H = _two_mode_siso()
    orders = np.array([2, 4, 6, 8])
    got_orders, misfit = misfit_scan(z, H, orders, subspace.row_basis(z, 9))
    np.testing.assert_array_equal(got_orders, orders)
    assert misfit[0] > 0.1  # one mode cannot fit two
    assert np.all(misfit[1:] < 1e-6)  # exact from order 4 on


def test_rounding_level_misfits_count_as_the_floor():
    misfit = np.array([0.806, 1.42e-14, 5.87e-15, 1.22e-10])
    assert order_at_floor(np.array([2, 4, 6, 8]), misfit) == 4


def test_misfit_scan_on_fewer_lines_and_with_unit_weights():
    z, H = _two_mode_siso()
    orders = np.array([2, 4, 6])
    basis = subspace.row_basis(z, 9)
    _, full = misfit_scan(z, H, orders, basis)
    _, few = misfit_scan(z, H, orders, basis, max_lines=60)
    _, weighted = misfit_scan(z, H, orders, basis, weights=np.ones(z.size))
    for m in (few, weighted):
        assert m[0] > 0.1 and np.all(m[1:] < 1e-6)
    np.testing.assert_allclose(weighted, full, rtol=1e-6, atol=1e-9)


def test_misfit_scan_stops_early_on_a_plateau():
    z, H = _two_mode_siso()
    orders = np.arange(2, 21, 2)
    got_orders, misfit = misfit_scan(
        z, H, orders, subspace.row_basis(z, 21), stop_after=4, patience=4
    )
    # the floor is reached at 4; at 8 the last 4 states (6, 8) improve on (2, 4) by < 10 %
    np.testing.assert_array_equal(got_orders, [2, 4, 6, 8])
    assert misfit.shape == (4,)
    # without stop_after, every order is evaluated
    all_orders, _ = misfit_scan(z, H, orders, subspace.row_basis(z, 21))
    np.testing.assert_array_equal(all_orders, orders)


def test_misfit_scan_is_the_same_on_any_number_of_workers():
    """The orders are evaluated in batches on the workers and the stop rule sees them in
    order: the same orders, misfits, residuals and models whatever ``jobs``."""
    z, H = _two_mode_siso()
    rng = np.random.default_rng(3)
    H = H + 1e-3 * (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape))
    variance = np.full(H.shape, 2e-6)
    orders = np.arange(2, 31, 2)
    basis = subspace.row_basis(z, 31)
    runs = []
    for jobs in (1, 2, 3):
        models: list = []
        got = misfit_scan(z, H, orders, basis, stop_after=6, patience=6, variance=variance,
                          params=2, z_alarm=3.0, models=models, jobs=jobs)
        runs.append((got, models))
    (first, models1) = runs[0]
    assert first[0].size < orders.size  # the stop rule ended it early
    for got, models in runs[1:]:
        for a, b in zip(first, got):
            np.testing.assert_array_equal(a, b)
        assert [m[0] for m in models] == [m[0] for m in models1]
        for (_, lam1, cv1), (_, lam, cv) in zip(models1, models):
            np.testing.assert_array_equal(lam1, lam)
            np.testing.assert_array_equal(cv1, cv)


@pytest.mark.parametrize("ny, nu", [(1, 1), (6, 1), (35, 3), (3, 74), (10, 2)])
def test_lines_for_orders_is_the_fewest_that_keep_every_automatic_order(ny, nu):
    from automodal.core import subspace
    from automodal.core.order import MAX_REFERENCE_ORDER, block_row_budget, lines_for_orders

    n = lines_for_orders(ny, nu)

    def holds(lines: int) -> bool:
        return all(block_row_budget(lines, a, b) >= subspace.scan_block_rows(
            MAX_REFERENCE_ORDER, a) for a, b in ((ny, nu), (nu, ny)))

    assert holds(n) and not holds(n - 1)
    assert lines_for_orders(ny, nu, max_order=2 * MAX_REFERENCE_ORDER) > n
