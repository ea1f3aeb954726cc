"""The modal model: one eigendecomposition, and every use of it equal to the direct one."""

from __future__ import annotations

import numpy as np
import pytest

from automodal.core import bilinear, reference, subspace
from automodal.core import simulate as sim
from automodal.core.modal import modes_of_discrete
from automodal.core.modal_model import ModalModel, synthesize
from automodal.core.pole_map import PoleMap


def _random_model(n_modes: int = 5, ny: int = 3, nu: int = 2, seed: int = 0):
    """A discrete-time model whose poles are all stable complex pairs (block-diagonal
    continuous-time ``A`` through the bilinear map), with a random real modal basis."""
    rng = np.random.default_rng(seed)
    wn = np.sort(rng.uniform(10.0, 100.0, n_modes))
    zeta = rng.uniform(0.01, 0.05, n_modes)
    blocks = []
    for w, z in zip(wn, zeta):
        sigma, wd = -z * w, w * np.sqrt(1 - z**2)
        blocks.append(np.array([[sigma, wd], [-wd, sigma]]))
    Ac = np.zeros((2 * n_modes, 2 * n_modes))
    for i, b in enumerate(blocks):
        Ac[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = b
    S = rng.standard_normal((2 * n_modes, 2 * n_modes)) + 3 * np.eye(2 * n_modes)
    Ac = S @ Ac @ np.linalg.inv(S)
    Bc = rng.standard_normal((2 * n_modes, nu))
    Cc = rng.standard_normal((ny, 2 * n_modes))
    Dc = rng.standard_normal((ny, nu)) * 0.1
    T = bilinear.default_scale(5.0, 120.0)
    return (*bilinear.c2d(Ac, Bc, Cc, Dc, T), T)


@pytest.fixture
def count_eig(monkeypatch):
    """Counts calls of ``np.linalg.eig`` (and keeps the sizes of the matrices)."""
    calls: list[tuple[int, ...]] = []
    real_eig = np.linalg.eig

    def counting(a):
        calls.append(np.shape(a))
        return real_eig(a)

    monkeypatch.setattr(np.linalg, "eig", counting)
    return calls


def test_one_eigendecomposition_serves_every_use(count_eig):
    A, B, C, D, T = _random_model()
    z = bilinear.to_unit_circle(np.linspace(20, 600, 50), T)
    m = ModalModel(A, B, C, D, T)
    m.modes()
    m.contributions()
    m.synthesize(z, np.arange(3))
    m.frequency_response(z)
    m.real_mode_vectors(4)
    assert len(count_eig) == 1


def test_given_eigendecomposition_is_not_repeated(count_eig):
    A, B, C, D, T = _random_model()
    eigen = np.linalg.eig(A)
    count_eig.clear()
    ModalModel(A, B, C, D, T, eigen=eigen).contributions()
    assert count_eig == []


def test_modes_equal_modes_of_discrete():
    A, B, C, D, T = _random_model(seed=1)
    direct = modes_of_discrete(A, C, T, B)
    mine = ModalModel(A, B, C, D, T).modes()
    np.testing.assert_array_equal(mine.poles, direct.poles)
    np.testing.assert_array_equal(mine.mu, direct.mu)
    np.testing.assert_array_equal(mine.shapes, direct.shapes)
    np.testing.assert_array_equal(mine.participation, direct.participation)
    shifted = ModalModel(A, B, C, D, T).modes(PoleMap(shift=0.5))
    np.testing.assert_array_equal(shifted.poles, direct.poles + 0.5)


def test_synthesis_keeping_every_mode_equals_frequency_response():
    A, B, C, D, T = _random_model(seed=2)
    z = bilinear.to_unit_circle(np.linspace(20, 600, 80), T)
    m = ModalModel(A, B, C, D, T)
    full = subspace.frequency_response(A, B, C, D, z)
    kept = m.synthesize(z, np.arange(len(m.modes())))
    np.testing.assert_allclose(kept, full, rtol=1e-10, atol=1e-12 * np.abs(full).max())
    np.testing.assert_allclose(m.frequency_response(z), full, rtol=1e-12)
    np.testing.assert_allclose(synthesize(A, B, C, D, z, np.arange(5), T), full, rtol=1e-10,
                               atol=1e-12 * np.abs(full).max())


def test_synthesis_with_no_mode_is_the_feed_through():
    A, B, C, D, T = _random_model(seed=3)
    z = bilinear.to_unit_circle(np.linspace(20, 600, 10), T)
    out = ModalModel(A, B, C, D, T).synthesize(z, np.array([], dtype=int))
    np.testing.assert_array_equal(out, np.broadcast_to(D, (10,) + D.shape))


def test_contributions_of_a_clean_model_are_dominant():
    A, B, C, D, T = _random_model(seed=4)
    c = ModalModel(A, B, C, D, T).contributions()
    assert c.shape == (5,)
    assert np.all(c > 0.3) and np.all(c < 1.5)


def test_no_real_pole_gives_no_real_mode_vector():
    A, B, C, D, T = _random_model(seed=5)
    assert ModalModel(A, B, C, D, T).real_mode_vectors(4).shape == (4 * 3, 0)


def test_reference_model_is_decomposed_once_and_keeps_its_path(count_eig):
    system = sim.damp(sim.chain(4), "rayleigh", zeta=0.02)
    freq = sim.frequency_lines(1.25 * sim.natural_frequencies_hz(system).max(), 300)
    data, _ = sim.simulate_test(system, [0, 2, 3], [3], freq, "displacement", noise=0.01, seed=0)
    w = 2 * np.pi * data.frequency[data.frequency > 0]
    H = data.frf[data.frequency > 0]
    T = bilinear.default_scale(w[0], w[-1])
    z = bilinear.to_unit_circle(w, T)
    scales = subspace.channel_scales(H)
    Hs = H / scales[None, :, None]
    lw = subspace.envelope_weights(Hs)
    count_eig.clear()
    ref = reference.build_reference(z, Hs, scales, lw, 24, T, (w[0], w[-1]), 0.2, 1.0)
    assert len(count_eig) == 1
    model = subspace.identify(z, H, 24, T, weights=lw)
    assert ref.model.path == model.path
    np.testing.assert_array_equal(ref.model.Ad, model.Ad)
    np.testing.assert_array_equal(ref.model.Cd, model.Cd)
    np.testing.assert_array_equal(ref.model.Dd, model.Dd)


def test_identify_reports_the_qr_path_when_it_ran():
    system = sim.damp(sim.chain(4), "rayleigh", zeta=0.02)
    freq = sim.frequency_lines(1.25 * sim.natural_frequencies_hz(system).max(), 300)
    data, _ = sim.simulate_test(system, [3], [3], freq, "displacement")
    w = 2 * np.pi * data.frequency[data.frequency > 0]
    T = bilinear.default_scale(w[0], w[-1])
    z = bilinear.to_unit_circle(w, T)
    H = data.frf[data.frequency > 0]
    assert subspace.identify(z, H, 8, T, method="qr").path == "qr"
    assert subspace.identify(z, H, 8, T, method="gram").path == "gram"


def test_pipeline_reports_the_reference_path_that_ran():
    from pathlib import Path

    from automodal.io.frf_file import read_frf
    from automodal.pipeline import identify
    from automodal.settings import Settings

    data = read_frf(str(Path(__file__).resolve().parents[1] / "sample_data" / "chain6.h5"))
    result = identify(data, Settings(n_bootstrap=4, jobs=1))
    assert result.orders["reference_path"] == result.reference_model.path
    assert result.orders["reference_path"] in ("gram", "qr")
