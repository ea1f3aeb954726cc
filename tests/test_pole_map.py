"""The map from the identified model's poles to the structure's (window decay, sampled
spectra), and the exactness it gives the output-only route on noise-free half spectra."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from automodal.core import simulate as sim
from automodal.core.pole_map import PoleMap
from automodal.errors import InputError
from automodal.frfdata import FRFData
from automodal.pipeline import identify
from automodal.settings import Settings

FS = 256.0


def test_identity_and_shift():
    s = np.array([-0.1 + 10j, -2.0 + 300j])
    assert PoleMap().is_identity
    np.testing.assert_array_equal(PoleMap()(s), s)
    np.testing.assert_array_equal(PoleMap(shift=0.5)(s), s + 0.5)
    np.testing.assert_array_equal(PoleMap(shift=0.5).model_omega(np.array([1.0, 2.0])),
                                  [1.0, 2.0])


def test_prewarped_lines_carry_discrete_poles_to_continuous_ones():
    """A discrete pole mu = exp(s / fs), seen at the prewarped lines, is the continuous
    pole s' = 2 fs tanh(s / 2 fs); the map gives s back."""
    pm = PoleMap(sample_rate=FS)
    s = np.array([-0.05 + 2j * np.pi * 1.2, -3.0 + 2j * np.pi * 90.0])
    mu = np.exp(s / FS)
    s_model = 2 * FS * (mu - 1) / (mu + 1)  # the bilinear image of mu with T = 1 / fs
    np.testing.assert_allclose(pm(s_model), s, rtol=1e-12)
    np.testing.assert_allclose(pm.to_model(s), s_model, rtol=1e-12)
    np.testing.assert_allclose(PoleMap(0.7, FS).to_model(PoleMap(0.7, FS)(s_model)), s_model,
                               rtol=1e-12)
    # the line exp(j w / fs) is the bilinear image of j w' (w' prewarped)
    w = 2 * np.pi * np.array([0.5, 10.0, 100.0])
    wp = pm.model_omega(w)
    np.testing.assert_allclose((1 + 1j * wp / (2 * FS)) / (1 - 1j * wp / (2 * FS)),
                               np.exp(1j * w / FS), rtol=1e-12)
    with pytest.raises(ValueError, match="Nyquist"):
        pm.model_omega(np.array([2 * np.pi * 130.0]))


def test_covariance_follows_the_derivative():
    pm = PoleMap(shift=0.3, sample_rate=100.0)
    s = np.array([-1.0 + 150j])
    cov = np.array([[[2e-4, 5e-5], [5e-5, 1e-4]]])
    J = np.empty((2, 2))
    h = 1e-6
    for k, d in enumerate((h, 1j * h)):  # numerical Jacobian of (Re, Im)
        diff = (pm(s + d) - pm(s - d))[0] / (2 * h)
        J[:, k] = diff.real, diff.imag
    np.testing.assert_allclose(pm.covariance(s, cov)[0], J @ cov[0] @ J.T, rtol=1e-6)


def _exact_half_spectra(lags: int, decay: float) -> tuple[np.ndarray, np.ndarray, sim.Modes]:
    """Half spectra of a lightly damped 5-DOF chain (1.2-8.1 Hz, 0.14-0.2 %) as
    :func:`automodal.core.spectra.half_spectra` makes them from the exact correlation:
    ``lags`` lags, an exponential window of ``decay``, a DFT of length ``lags``."""
    system = sim.chain(5, 1.0, 1.0)
    k = (1.2 / sim.natural_frequencies_hz(system)[0]) ** 2
    system = sim.damp(sim.chain(5, 1.0, k), "rayleigh", 0.002)
    A, B, C, _ = sim.state_space(system, None, list(range(5)), "velocity")
    n = A.shape[0]
    E = scipy.linalg.expm(np.block([[A, B], [np.zeros((5, n + 5))]]) / FS)
    Ad, Bd = E[:n, :n], E[:n, n:]
    P = scipy.linalg.solve_discrete_lyapunov(Ad, Bd @ Bd.T)
    X = P @ C[[0, 4]].T  # E[x(t) y_ref(t)^T]: R(tau) = C Ad^tau X
    Aw = np.exp(-decay / FS) * Ad
    trunc = np.eye(n) - np.linalg.matrix_power(Aw, lags)
    freq = np.arange(1, int(100.0 * lags / FS) + 1) * FS / lags
    z = np.exp(2j * np.pi * freq / FS)
    inv = np.linalg.inv(np.eye(n)[None] - Aw[None] / z[:, None, None])
    G = (np.einsum("ij,fjk,kl->fil", C, inv, trunc @ X) - 0.5 * C @ X) / FS
    return freq, G, sim.exact_modes(system)


@pytest.mark.parametrize("decay", [0.0, 0.58])
def test_noise_free_half_spectra_give_the_poles_exactly(decay):
    freq, G, truth = _exact_half_spectra(2048, decay)
    data = FRFData(frequency=freq, frf=G, quantity="velocity",
                   attributes={"analysis": "operational", "window_decay_per_s": decay,
                               "discrete_sample_rate_hz": FS})
    result = identify(data, Settings(n_bootstrap=10, jobs=1))
    assert result.orders["n0"] == 10  # the structure's order: the prewarped data are exact
    modes = result.physical_modes
    assert len(modes) == 5
    f = np.array([m.frequency_hz for m in modes])
    z = np.array([m.damping_ratio for m in modes])
    np.testing.assert_allclose(f, truth.frequency_hz, rtol=1e-6)
    np.testing.assert_allclose(z, truth.damping_ratio, rtol=1e-6)


def test_bad_map_attributes_are_refused():
    freq, G, _ = _exact_half_spectra(512, 0.0)
    for attrs, match in (({"discrete_sample_rate_hz": float("nan")}, "sample rate"),
                         ({"discrete_sample_rate_hz": 150.0}, "Nyquist"),
                         ({"window_decay_per_s": "fast"}, "window_decay_per_s")):
        data = FRFData(frequency=freq, frf=G, quantity="velocity", attributes=attrs)
        with pytest.raises(InputError, match=match):
            identify(data, Settings(n_bootstrap=2, jobs=1))
