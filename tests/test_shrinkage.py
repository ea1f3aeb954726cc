"""Empirical-Bayes shrinkage (:mod:`automodal.core.shrinkage`) and its use for the refined
modes' shapes."""

from __future__ import annotations

import numpy as np
import pytest

from automodal.core import simulate as sim
from automodal.core.refine import refine_poles, residue_shapes
from automodal.core.shrinkage import prior_variance, shrunk


def _mac(a, b):
    return abs(np.vdot(a, b)) ** 2 / (np.vdot(a, a).real * np.vdot(b, b).real)


@pytest.mark.parametrize("seed", range(5))
def test_the_prior_variance_is_recovered_from_entries_of_unequal_errors(seed):
    rng = np.random.default_rng(seed)
    n, tau2 = 4000, 2.0
    s = 10.0 ** rng.uniform(-3, 1, n)
    r = sim.complex_gaussian((n,), np.sqrt(tau2), rng) + sim.complex_gaussian((n,), np.sqrt(s), rng)
    assert prior_variance(r, s) == pytest.approx(tau2, rel=0.1)


def test_well_known_entries_keep_their_value_and_a_noisy_one_goes_to_zero():
    r = np.array([1.0, 0.5j, -0.7, 0.9 + 0.3j])
    s = np.array([1e-8, 1e-8, 1e-8, 25.0])  # the last: error 5, five times the others' size
    out = shrunk(r, s)
    np.testing.assert_allclose(out[:3], r[:3], rtol=1e-6)
    assert abs(out[3]) < 0.05 * abs(r[3])


def test_exact_entries_are_left_alone_and_pure_noise_gives_zeros():
    r = np.array([1.0, 2.0, 3.0j])
    np.testing.assert_array_equal(shrunk(r, np.zeros(3)), r)
    np.testing.assert_array_equal(shrunk(r, np.full(3, np.nan)), r)
    assert np.all(shrunk(0.01 * r, np.ones(3)) == 0)


def _proportional_chain():
    system = sim.damp(sim.chain(4), zeta=0.02)
    freq = sim.frequency_lines(1.25 * sim.natural_frequencies_hz(system).max(), 800)
    data, modes = sim.simulate_test(system, range(4), [0, 3], freq, "displacement",
                                    noise=0.0, seed=0)
    wn = 2 * np.pi * modes.frequency_hz
    z = modes.damping_ratio
    return 2 * np.pi * freq, data.frf, wn * (-z + 1j * np.sqrt(1 - z**2))


def test_each_residue_entry_has_the_variance_the_fit_reports():
    """Noise proportional to ``|H|`` is not separable, so the fit's separable weights are not
    each entry's: the variance it reports per entry (``G V G^T``) must still be that of the
    residues over noise draws (100 draws: the sampling error of a variance is 14 %)."""
    omega, H0, poles = _proportional_chain()
    rng = np.random.default_rng(7)
    std = 0.05 * np.abs(H0)
    residues, predicted = [], []
    for _ in range(100):
        fit = refine_poles(omega, H0 + std * sim.complex_gaussian(std.shape, 1.0, rng),
                           std**2, poles, np.zeros(0))
        assert fit.refined.all()
        residues.append(fit.residues)
        predicted.append(fit.entry_variance)
    ratio = np.var(np.array(residues), axis=0) / np.mean(predicted, axis=0)
    assert 0.85 < np.median(ratio) < 1.15, np.median(ratio)
    assert np.all((ratio > 0.55) & (ratio < 1.6)), (ratio.min(), ratio.max())


def test_a_channel_whose_noise_buries_the_mode_does_not_set_its_shape():
    """Two modes seen by four outputs and one input, noise at 5 % of ``|H|``: output 3 is
    dominated by the upper mode, and its noise at the lower mode's lines is larger than the
    lower mode's whole response in outputs 0-2. Output 3's least-squares residue is then
    mostly error and the unshrunk shape points at it (seed 419 f_24 of the family had
    this); shrunk, the shape is the true one."""
    lam = np.array([2 * np.pi * 10 * (-0.01 + 1j), 2 * np.pi * 14 * (-0.01 + 1j)])
    phi = np.array([[1.0, 0.6, -0.4, 0.02], [1e-4, -1e-4, 2e-4, 1.0]]).T
    omega = 2 * np.pi * np.linspace(7, 17, 1000)
    s = 1j * omega[:, None]
    terms = 1 / (s - lam) + 1 / (s - lam.conj())
    H0 = (terms @ (phi * np.array([1e-4, 1.0])).T)[:, :, None]
    macs_raw, macs = [], []
    rng = np.random.default_rng(3)
    std = 0.05 * np.abs(H0)
    for _ in range(10):
        fit = refine_poles(omega, H0 + std * sim.complex_gaussian(H0.shape, 1.0, rng),
                           std**2, lam, np.zeros(0))
        assert fit.refined.all()
        raw = residue_shapes(fit.residues, std**2, fit.residue_variance)
        got = residue_shapes(fit.residues, std**2, fit.residue_variance, fit.entry_variance)
        macs_raw.append(_mac(raw[:, 0], phi[:, 0]))
        macs.append(_mac(got[:, 0], phi[:, 0]))
        assert _mac(got[:, 1], phi[:, 1]) > 0.999
    assert np.median(macs_raw) < 0.8, macs_raw  # the defect this guards against
    assert np.median(macs) > 0.98 and min(macs) > 0.9, macs
