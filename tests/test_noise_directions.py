"""The directions of the noise-whitened projection (subspace.noise_whitened_spectrum,
order.noise_directions), and the significant order they cap."""

from __future__ import annotations

import numpy as np
import pytest

from automodal.core import bilinear, order, subspace, whitening
from automodal.core import simulate as sim


def _chain_frf(n_lines: int = 1000, outputs=(0, 1, 2, 3, 4, 5), inputs=(0,), n_dof: int = 6):
    """Noise-free receptances of a 6-DOF chain (the simulate command's default system), its
    unit-circle points and bilinear scale."""
    system = sim.damp(sim.chain(n_dof), "rayleigh", zeta=0.01)
    freq = sim.frequency_lines(1.25 * sim.natural_frequencies_hz(system).max(), n_lines)
    data, _ = sim.simulate_test(system, list(outputs), list(inputs), freq, "displacement",
                                noise=0.0)
    keep = data.frequency > 0
    w = 2 * np.pi * data.frequency[keep]
    T = bilinear.default_scale(w[0], w[-1])
    return bilinear.to_unit_circle(w, T), data.frf[keep]


def _complex_noise(rng: np.random.Generator, variance: np.ndarray) -> np.ndarray:
    """Circular complex Gaussian noise of the given variance (``E |e|^2``) per entry."""
    shape = variance.shape
    return np.sqrt(variance / 2) * (rng.standard_normal(shape) + 1j * rng.standard_normal(shape))


def _directions(z, H, variance, q):
    basis = subspace.row_basis(z, q)
    weights = np.ones(z.size)
    S = subspace.single_schur(basis, H, weights)
    ev, columns = subspace.noise_whitened_spectrum(S, basis, variance, weights)
    return ev, order.noise_directions(ev, S.shape[0], columns), columns


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("shape,q", [((800, 1, 1), 40), ((1500, 6, 2), 12), ((600, 20, 3), 5)])
def test_pure_noise_of_any_variance_shape_stays_under_the_margin(seed, shape, q):
    # the noise covariance, not a separable approximation of it: variances that differ by
    # entry and line (deep notches in some entries, as proportional noise has at their
    # antiresonances) whiten to eigenvalues near 1
    rng = np.random.default_rng(seed)
    N = shape[0]
    z = np.exp(1j * np.linspace(0.05, np.pi - 0.05, N))
    shape_of_variance = np.exp(rng.normal(0.0, 1.5, size=(1, *shape[1:])))
    notches = 1e-3 + np.abs(np.sin(np.linspace(0, rng.uniform(3, 9), N)))[:, None, None] ** 2
    variance = shape_of_variance * notches ** rng.uniform(0.5, 1.5, size=(1, *shape[1:]))
    H = _complex_noise(rng, variance)
    ev, directions, columns = _directions(z, H, variance, q)
    edge = (1 + np.sqrt(ev.size / columns)) ** 2
    assert 0.5 < np.median(ev) < 1.5  # whitened noise: eigenvalues near 1
    assert ev[0] < order.NOISE_EIGENVALUE_MARGIN * edge
    assert directions == 0  # nothing above the noise


def test_a_noisy_chain_shows_its_twelve_states():
    z, H = _chain_frf()
    rng = np.random.default_rng(3)
    variance = (0.01 * np.abs(H)) ** 2  # proportional noise, 1 %
    ev, directions, _ = _directions(z, H + _complex_noise(rng, variance), variance, 30)
    assert directions == 12
    assert ev[11] > 1000 * ev[12]


def test_noise_free_data_show_exactly_their_order():
    z, H = _chain_frf(outputs=(0, 2, 5))
    variance = np.full(H.shape, 1e-14 * np.mean(np.abs(H) ** 2))  # the model's own precision
    ev, directions, _ = _directions(z, H, variance, 12)
    assert directions == 12
    assert ev[11] > 1e6 * ev[12]


def test_a_projection_without_a_noise_floor_bounds_nothing():
    ev = np.full(20, 1e3)
    assert order.noise_directions(ev, 20, 2000) is None
    assert order.noise_directions(np.r_[np.full(17, 1e3), np.ones(3)], 20, 2000) is None
    assert order.noise_directions(np.r_[np.full(15, 1e3), np.ones(5)], 20, 2000) == 16
    assert order.noise_directions(np.r_[np.full(5, 1e3), np.ones(15)], 20, 2000) == 6  # even


def test_capped_order_takes_the_smallest_scanned_order_holding_twice_the_directions():
    orders = np.r_[np.arange(2, 61, 2), 64, 68, 72]
    assert order.DIRECTIONS_EXCESS == 2.0
    assert order.capped_order(orders, 68, 12) == 24
    assert order.capped_order(orders, 68, 31) == 64  # 62 states: the next scanned order
    assert order.capped_order(orders, 10, 12) == 10  # a cap, never a raise
    assert order.capped_order(orders, 68, None) == 68
    assert order.capped_order(orders, 68, 0) == 2  # pure noise: the smallest order
    assert order.capped_order(orders, 70, 45) == 70  # beyond the scan: no cap


@pytest.mark.parametrize("seed", range(6))
def test_proportional_noise_on_a_chain_no_longer_inflates_the_order(seed):
    # 1 % proportional noise on the simulate command's 6-DOF chain, force at DOF 1, weighted
    # as the pipeline weighs it: the subspace models of the true order leave many times the
    # noise (their own bias at the antiresonances), and the significance test alone chose
    # 14 to 58 states for these 6 modes (68 in the pipeline, seed 0 of the command)
    z, H = _chain_frf()
    rng = np.random.default_rng(seed)
    variance = (0.01 * np.abs(H)) ** 2
    Hn = H + _complex_noise(rng, variance)
    scales = subspace.channel_scales(Hn)
    Hs = Hn / scales[None, :, None]
    var_s = variance / (scales**2)[None, :, None]
    line_weights, _ = whitening.whitening(var_s)
    choice = order.select_orders(z, Hs, line_weights, variance=var_s)
    assert choice.noise_directions == 12
    assert choice.rule == "significance" and 12 <= choice.n0 <= 24
    if seed == 1:
        uncapped = order.significant_order(
            choice.scanned, choice.chi2, whitening.mode_parameters(6, 1), order.ORDER_Z,
            order.ORDER_TOLERANCE)
        assert uncapped > 50  # what the cap keeps off
