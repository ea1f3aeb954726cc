"""Thinning of bands sampled far more finely than their resonances
(``automodal/core/resolution.py``) and its place in the pipeline."""

from __future__ import annotations

import numpy as np
import pytest

from automodal.core import resolution
from automodal.core import simulate as sim
from automodal.pipeline import identify
from automodal.settings import Settings


def chain_frf(n_lines: int, zeta: float = 0.01, noise: float = 0.01, seed: int = 0):
    """A 4-DOF chain's receptances (4 outputs, 1 input) on ``n_lines`` lines, additive
    noise of ``noise`` times each FRF's RMS, and that noise's variance."""
    system = sim.damp(sim.chain(4), zeta=zeta)
    lines = sim.frequency_lines(1.25 * sim.natural_frequencies_hz(system).max(), n_lines)
    H = sim.frf(system, lines, [0, 1, 2, 3], [3])
    rms = np.sqrt(np.mean(np.abs(H) ** 2, axis=0))
    variance = np.broadcast_to((noise * rms) ** 2, H.shape).copy()
    rng = np.random.default_rng(seed)
    H = H + np.sqrt(variance / 2) * (rng.standard_normal(H.shape)
                                     + 1j * rng.standard_normal(H.shape))
    return lines, H, variance


def half_power_lines(lines: np.ndarray, zeta: float) -> float:
    """Lines across the narrowest half-power band (``2 |Re lambda|``) of the chain's modes."""
    system = sim.damp(sim.chain(4), zeta=zeta)
    n = system.M.shape[0]
    Minv = np.linalg.inv(system.M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ system.K, -Minv @ system.C]])
    poles = np.linalg.eigvals(A)
    return float(np.min(2 * np.abs(poles.real)) / (2 * np.pi) / (lines[1] - lines[0]))


def test_bands_up_to_the_limit_keep_every_line():
    _, H, variance = chain_frf(resolution.THIN_ABOVE_LINES)
    k, width = resolution.thinning_step(H, variance)
    assert k == 1 and np.isnan(width)


def test_a_finely_sampled_band_is_thinned_towards_the_limit():
    lines, H, variance = chain_frf(200_000)
    assert half_power_lines(lines, 0.01) > 500  # the first mode: ~590 lines wide
    k, width = resolution.thinning_step(H, variance)
    assert k == 10  # 200 000 lines towards 20 000
    assert width >= k * resolution.LINES_PER_HALF_POWER_BAND


def test_the_narrowest_resonance_keeps_its_lines():
    """Half-power bands of 3-5 lines: every line is kept, however many there are."""
    lines, H, variance = chain_frf(60_000, zeta=2e-4)
    assert 2 < half_power_lines(lines, 2e-4) < 6
    k, width = resolution.thinning_step(H, variance)
    assert k == 1 and width < 2 * resolution.LINES_PER_HALF_POWER_BAND


def test_the_step_keeps_ten_lines_across_the_narrowest_peak():
    lines, H, variance = chain_frf(100_000, zeta=0.002)
    wide = half_power_lines(lines, 0.002)  # ~ 50 lines: at most a step of 5
    k, width = resolution.thinning_step(H, variance)
    assert 2 <= k <= wide / resolution.LINES_PER_HALF_POWER_BAND
    assert width == pytest.approx(wide, rel=0.3)


def test_pure_noise_is_not_thinned():
    """No peak stands out of the noise: nothing says how fine the lines must be."""
    rng = np.random.default_rng(1)
    shape = (50_000, 2, 1)
    H = rng.standard_normal(shape) + 1j * rng.standard_normal(shape)
    k, width = resolution.thinning_step(H, np.full(shape, 2.0))
    assert k == 1 and np.isnan(width)


def test_a_noisy_flank_does_not_stop_the_thinning():
    """Maxima of a noise floor 1/21 of a resonance's flank cross its half-power level by a
    dip of the noise; they must not count as peaks two lines wide (they did at 6 noise
    standard deviations)."""
    lines, H, variance = chain_frf(200_000, noise=0.05, seed=3)
    k, _ = resolution.thinning_step(H, variance)
    assert k == 10


def test_thinning_is_wired_into_the_pipeline_and_exact_data_stay_exact(monkeypatch):
    monkeypatch.setattr(resolution, "THIN_ABOVE_LINES", 1000)
    system = sim.damp(sim.chain(4), "rayleigh", zeta=0.02)
    true_hz = np.sort(sim.natural_frequencies_hz(system))
    lines = sim.frequency_lines(1.25 * true_hz.max(), 6000)
    data, _ = sim.simulate_test(system, [0, 1, 2, 3], [3], lines, "displacement", noise=0.0)
    res = identify(data, Settings(seed=0, n_bootstrap=8, jobs=1))
    assert any("every" in w and "th line was kept" in w for w in res.warnings), res.warnings
    assert 1000 <= res.n_lines < 6000
    found = np.sort([m.frequency_hz for m in res.modes if m.physical])
    assert found.size == true_hz.size
    assert np.max(np.abs(found - true_hz) / true_hz) < 1e-6


def test_thinned_noisy_band_finds_every_mode_with_honest_intervals(monkeypatch):
    monkeypatch.setattr(resolution, "THIN_ABOVE_LINES", 2000)
    system = sim.damp(sim.chain(4), zeta=0.01)
    true_hz = np.sort(sim.natural_frequencies_hz(system))
    lines = sim.frequency_lines(1.25 * true_hz.max(), 12_000)
    data, _ = sim.simulate_test(system, [0, 1, 2, 3], [3], lines, "displacement", noise=0.01,
                                seed=4)
    res = identify(data, Settings(seed=0, n_bootstrap=20, jobs=1))
    assert res.n_lines < 12_000
    modes = sorted((m for m in res.modes if m.physical), key=lambda m: m.frequency_hz)
    assert len(modes) == true_hz.size
    for m, f in zip(modes, true_hz):
        assert abs(m.frequency_hz - f) / f < 1e-3
        lo, hi = m.frequency_ci95_hz
        assert hi - lo > 0
