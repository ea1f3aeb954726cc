"""Whitening by the noise model, the order significance test and the physicalness vetoes
(issue 13)."""

from __future__ import annotations

import numpy as np
import pytest

from automodal.core import clustering, physicalness, whitening
from automodal.core.modal import ModeSet
from automodal.core.modal_model import ModalModel
from automodal.core.order import excessive_order, significant_order
from automodal.core.summary import summarise_clusters


def test_separable_variance_recovers_a_separable_model():
    rng = np.random.default_rng(0)
    v = np.exp(rng.normal(size=50))
    a = np.exp(rng.normal(size=4))
    b = np.exp(rng.normal(size=2))
    var = v[:, None, None] * a[None, :, None] * b[None, None, :]
    line, out = whitening.separable_variance(var)
    fit = line[:, None, None] * out[None, :, None]
    # the input factor is folded into the output factor as its geometric mean
    want = var / b[None, None, :] * np.exp(np.mean(np.log(b)))
    np.testing.assert_allclose(fit[..., 0], want[..., 0], rtol=1e-10)
    np.testing.assert_allclose(want[..., 0], want[..., 1], rtol=1e-10)
    assert np.exp(np.mean(np.log(line))) == pytest.approx(1.0)


def test_whitening_weights_have_mean_one_and_scales_are_noise_std():
    var = np.ones((20, 3, 1)) * np.array([1.0, 4.0, 9.0])[None, :, None]
    w, s = whitening.whitening(var)
    np.testing.assert_allclose(w, 1.0)
    np.testing.assert_allclose(s, [1.0, 2.0, 3.0])


def test_whitened_residual_of_noise_is_chi_square_with_two_dof_per_entry():
    rng = np.random.default_rng(1)
    var = rng.uniform(0.5, 2.0, size=(4000, 2, 1))
    e = np.sqrt(var / 2) * (rng.normal(size=var.shape) + 1j * rng.normal(size=var.shape))
    chi2 = whitening.whitened_residual(e, np.zeros_like(e), var)
    dof = 2 * e.size
    assert abs(chi2 - dof) < 4 * np.sqrt(2 * dof)


def test_mode_parameters():
    assert whitening.mode_parameters(1, 1) == 4
    assert whitening.mode_parameters(20, 3) == 46


def test_mode_snr2_is_the_whitened_energy_of_the_modes_own_term():
    mu = 0.9 * np.exp(1j * 0.5)
    A = np.array([[mu.real, -mu.imag], [mu.imag, mu.real]])
    B = np.array([[1.0], [0.0]])
    C = np.array([[0.0, 1.0], [1.0, 1.0]])
    D = np.zeros((2, 1))
    z = np.exp(1j * np.linspace(0.1, 1.0, 300))
    model = ModalModel(A, B, C, D, 1.0)
    H = model.frequency_response(z)
    var = np.full(H.shape, 0.01)
    snr2 = whitening.mode_snr2(model, z, var)
    assert snr2.shape == (1,)
    assert snr2[0] == pytest.approx(2 * np.sum(np.abs(H) ** 2) / 0.01, rel=1e-10)


def test_significant_order_stops_where_gains_are_those_of_noise():
    orders = np.arange(2, 42, 2)
    p = 10
    true = 12
    # large drops up to the true order, then what fitting noise gives (p per mode)
    chi2 = np.where(orders < true, 1e6 / orders**3, 0.0) + 5000.0
    chi2 = chi2 - np.maximum(orders - true, 0) / 2 * p
    assert significant_order(orders, chi2, p, 3.0) == true


def test_significant_order_sees_a_late_significant_drop():
    orders = np.arange(2, 42, 2)
    chi2 = 5000.0 - orders * 1.0
    chi2[orders >= 30] -= 2000.0  # a mode found only at order 30
    assert significant_order(orders, chi2, 4, 3.0) == 30


def test_significant_order_tolerance_ignores_small_relative_wander():
    orders = np.arange(2, 22, 2)
    chi2 = np.array([9e6, 5e6, 1e6, 1.02e6, 0.99e6, 0.97e6, 1.01e6, 0.98e6, 0.96e6, 1e6])
    assert significant_order(orders, chi2, 4, 3.0, tolerance=0.1) == 6
    assert significant_order(orders, chi2, 4, 3.0, tolerance=0.0) == 18


def test_excessive_order_factor():
    assert excessive_order(40, 400) == 120
    assert excessive_order(40, 400, 1.5) == 60
    assert excessive_order(10, 400, 1.5) == 30


def test_snr_feature_is_zero_for_what_noise_gives():
    assert physicalness.snr_feature(8.0, 8) == pytest.approx(0.0, abs=1e-9)
    assert physicalness.snr_feature(800.0, 8) == pytest.approx(2.0)
    assert physicalness.snr_feature(0.0, 8) == physicalness.SNR_RANGE[0]
    assert physicalness.snr_feature(1e12, 8) == physicalness.SNR_RANGE[1]


def test_snr_prototypes_are_classified_as_themselves():
    f = np.vstack([physicalness.SNR_PHYSICAL_PROTOTYPE, physicalness.SNR_NOISE_PROTOTYPE])
    phys = physicalness.physicalness(f, snr=True)
    assert phys[0] > 0.99 and phys[1] < 0.01


def _one_cluster(n_members: int, n_bootstrap: int, snr2: float):
    """A cluster of ``n_members`` bootstrap modes, perfect in every other feature."""
    pole = -0.01 * 60 + 1j * 60
    ref = ModeSet(poles=np.array([pole]), mu=np.array([0.5 + 0.5j]),
                  shapes=np.ones((3, 1), complex) / np.sqrt(3), participation=None)
    sub = clustering.ReferenceSubspaces(groups=[np.array([0])], bases=[np.ones((3, 1))],
                                        noise_basis=np.zeros((3, 0)), capacity=[1])
    labels = np.zeros(n_members, dtype=int)
    return summarise_clusters(
        labels, np.ones(n_members), np.full(n_members, pole),
        np.ones((3, n_members), complex) / np.sqrt(3), np.arange(n_members), sub, ref,
        np.ones(3), np.ones(1), n_bootstrap, 0.5, snr2=np.array([snr2]), params=12,
    )


def test_a_one_member_cluster_is_never_physical():
    (mode,) = _one_cluster(1, 1, 1e8)
    assert not mode.physical and mode.physicalness == 0.0


def test_a_minority_cluster_is_never_physical():
    (mode,) = _one_cluster(40, 100, 1e8)
    assert not mode.physical and mode.physicalness == 0.0


def test_a_majority_cluster_with_high_snr_is_physical():
    (mode,) = _one_cluster(95, 100, 1e5)
    assert mode.physical
    assert physicalness.SNR_FEATURE_NAME in mode.features


def test_a_majority_cluster_at_the_snr_of_noise_is_not_physical():
    # p = 12 parameters: fitting noise gives SNR^2 about 12 (+- 5)
    (mode,) = _one_cluster(95, 100, 12.0)
    assert not mode.physical and mode.physicalness == 0.0
    assert physicalness.vetoed(0.95, 95, 12.0 + 3 * np.sqrt(24) - 0.1, 12)
    assert not physicalness.vetoed(0.95, 95, 12.0 + 3 * np.sqrt(24) + 0.1, 12)


# ---------------------------------------------------------------------------------------
# The pipeline's use of the noise model
# ---------------------------------------------------------------------------------------


def _noisy_chain(noise: float = 0.02, seed: int = 3):
    from automodal.core import simulate as sim

    system = sim.damp(sim.chain(4), zeta=0.01)
    freq = sim.frequency_lines(1.25 * sim.natural_frequencies_hz(system).max(), 800)
    return sim.simulate_test(system, range(4), [3], freq, noise=noise, seed=seed,
                             noise_kind="additive")


def test_exact_system_order_with_the_noise_model_of_noise_free_data():
    from automodal.core import bilinear, noise, order
    from automodal.core import simulate as sim

    system = sim.damp(sim.chain(3), "rayleigh", zeta=0.02)
    freq = sim.frequency_lines(1.25 * sim.natural_frequencies_hz(system).max(), 400)
    data, _ = sim.simulate_test(system, [0, 1, 2], [2], freq, "displacement", noise=0.0)
    w = 2 * np.pi * data.frequency
    z = bilinear.to_unit_circle(w, bilinear.default_scale(w[0], w[-1]))
    var = noise.estimate_noise(data.frf).variance
    lw, scales = whitening.whitening(var)
    Hs = data.frf / scales[None, :, None]
    choice = order.select_orders(z, Hs, lw, variance=var / (scales**2)[None, :, None])
    assert choice.n0 == 6 and choice.rule == "significance"
    assert choice.reference == order.excessive_order(6, choice.limit, order.SIGNIFICANT_EXCESS)


def test_result_reports_the_noise_model_and_finds_the_modes():
    from automodal.pipeline import Settings, identify

    data, modes = _noisy_chain()
    r = identify(data, Settings(seed=1, n_bootstrap=30, weighting="noise"))
    assert r.noise is not None and r.noise.source == "data"
    assert set(r.noise.output_level) == set(data.output_names)
    for lvl in r.noise.output_level.values():
        assert 0.005 < lvl < 0.08
    assert r.noise.dispersion >= 1.0
    found = np.array([m.frequency_hz for m in r.physical_modes])
    for f in modes.frequency_hz:
        assert np.min(np.abs(found - f)) < 0.01 * f
    assert r.orders["n0_rule"] == "significance"


def test_noise_bootstrap_runs_says_so_and_is_reproducible():
    from automodal.pipeline import Settings, identify

    data, modes = _noisy_chain()
    s = Settings(seed=2, n_bootstrap=20, resample="noise", weighting="noise")
    a = identify(data, s)
    b = identify(data, Settings(seed=2, n_bootstrap=20, resample="noise", weighting="noise",
                                 jobs=1))
    assert any("bootstrap of the noise model" in w for w in a.warnings)
    np.testing.assert_array_equal(a.poles.frequency_hz, b.poles.frequency_hz)
    found = np.array([m.frequency_hz for m in a.physical_modes])
    for f in modes.frequency_hz:
        assert np.min(np.abs(found - f)) < 0.01 * f


def test_noise_resampling_needs_the_noise_weighting():
    from automodal.settings import Settings, SettingsError

    with pytest.raises(SettingsError, match="resample"):
        Settings(resample="noise", weighting="envelope")
    with pytest.raises(SettingsError, match="weighting"):
        Settings(weighting="bogus")


def test_output_rank_counts_the_directions_above_the_noise():
    rng = np.random.default_rng(3)
    N, ny, nu, r = 200, 12, 2, 5
    shapes = rng.normal(size=(ny, r))
    H = np.einsum("ir,krj->kij", shapes, rng.normal(size=(N, r, nu)) * 10.0).astype(complex)
    var = np.full(H.shape, 1e-2)
    H += 0.1 * (rng.normal(size=H.shape) + 1j * rng.normal(size=H.shape)) / np.sqrt(2)
    assert whitening.output_rank(H, var) == r
    # pure noise has no direction above it, full-rank data all of them
    assert whitening.output_rank(H - H + 0.1 * rng.normal(size=H.shape), var) == 0
    full = 10.0 * rng.normal(size=H.shape)
    assert whitening.output_rank(full, var) == ny


def test_a_rank_of_one_member_neither_counts_nor_is_physical():
    """A pair cluster whose second rank one replicate alone produced is one mode: found by
    97 of 100 replicates, it is physical; the lone pole is not."""
    poles = np.array([-0.01 * 60 + 1j * 60, -0.01 * 61 + 1j * 61])
    ref = ModeSet(poles=poles, mu=np.array([0.5 + 0.5j, 0.5 + 0.5j]),
                  shapes=np.ones((3, 2), complex) / np.sqrt(3), participation=None)
    sub = clustering.ReferenceSubspaces(groups=[np.array([0, 1])], bases=[np.eye(3)[:, :2]],
                                        noise_basis=np.zeros((3, 0)), capacity=[2])
    members = np.append(np.full(97, poles[0]), poles[1])
    replicate = np.append(np.arange(97), 0)  # replicate 0 found both
    modes = summarise_clusters(
        np.zeros(98, dtype=int), np.ones(98), members, np.ones((3, 98), complex) / np.sqrt(3),
        replicate, sub, ref, np.ones(3), np.ones(2), 100, 0.5, snr2=np.array([1e8, 1e8]),
        params=12,
    )
    main, lone = sorted(modes, key=lambda m: m.n_members, reverse=True)
    assert main.n_members == 97 and main.features["occurrence"] == pytest.approx(0.97)
    assert main.physical
    assert lone.n_members == 1 and not lone.physical and lone.physicalness == 0.0


def test_a_rank_no_replicate_produced_does_not_count():
    """A pair cluster of the reference model whose replicates all found one pole: one mode,
    physical when a majority found it."""
    poles = np.array([-0.01 * 60 + 1j * 60, -0.01 * 61 + 1j * 61])
    ref = ModeSet(poles=poles, mu=np.array([0.5 + 0.5j, 0.5 + 0.5j]),
                  shapes=np.ones((3, 2), complex) / np.sqrt(3), participation=None)
    sub = clustering.ReferenceSubspaces(groups=[np.array([0, 1])], bases=[np.eye(3)[:, :2]],
                                        noise_basis=np.zeros((3, 0)), capacity=[2])
    (mode,) = summarise_clusters(
        np.zeros(90, dtype=int), np.ones(90), np.full(90, poles[0]),
        np.ones((3, 90), complex) / np.sqrt(3), np.arange(90), sub, ref, np.ones(3),
        np.ones(2), 100, 0.5, snr2=np.array([1e8, 1e8]), params=12,
    )
    assert mode.features["occurrence"] == pytest.approx(0.9) and mode.physical


def test_mode_snr2_sums_over_the_lines_of_a_mode_narrower_than_the_line_step():
    # one mode of half-power bandwidth a third of a line spacing and one broad mode, on
    # 6000 lines: the SNR^2 from the default ~1000 lines must be that of all lines (even
    # spread lines, one in six, missed or over-weighted the sharp peak)
    N = 6000
    theta = np.linspace(0.05, 2.5, N)
    step = theta[1] - theta[0]
    poles = [np.exp(-step / 6 + 1j * theta[2000] + 1j * 0.37 * step),
             np.exp(-0.02 + 1j * 1.8)]
    A = np.zeros((4, 4))
    for k, mu in enumerate(poles):
        A[2 * k:2 * k + 2, 2 * k:2 * k + 2] = [[mu.real, -mu.imag], [mu.imag, mu.real]]
    B = np.array([[1.0], [0.0], [1.0], [0.0]])
    C = np.array([[0.0, 1.0, 0.3, 1.0], [1.0, 1.0, 0.0, 2.0]])
    model = ModalModel(A, B, C, np.zeros((2, 1)), 1.0)
    z = np.exp(1j * theta)
    var = np.full((N, 2, 1), 0.01) * np.linspace(1.0, 3.0, N)[:, None, None]
    every = whitening.mode_snr2(model, z, var, max_lines=N)
    default = whitening.mode_snr2(model, z, var)
    np.testing.assert_allclose(default, every, rtol=0.02)
    for jobs in (2, None):  # the columns and the parts of the Gram matrix on workers
        np.testing.assert_array_equal(whitening.mode_snr2(model, z, var, jobs=jobs), default)


def test_mode_snr2_is_the_regression_formed_column_by_column():
    # five close and overlapping modes seen by three outputs and two inputs, a variance
    # that is not separable: the SNR^2 (every line taken) must be the first element of
    # the inverse of mode a's 2 x 2 block of G^-1 (what the residual grows by when its two
    # columns are left out), G the Gram matrix of the real regression whose columns are
    # each mode's term plus its conjugate's and i times their difference, formed here
    # entry by entry
    rng = np.random.default_rng(5)
    mus = 0.97 * np.exp(1j * np.array([0.50, 0.52, 0.55, 0.9, 1.3]))
    n = 2 * mus.size
    A = np.zeros((n, n))
    for k, mu in enumerate(mus):
        A[2 * k:2 * k + 2, 2 * k:2 * k + 2] = [[mu.real, -mu.imag], [mu.imag, mu.real]]
    model = ModalModel(A, rng.normal(size=(n, 2)), rng.normal(size=(3, n)),
                       np.zeros((3, 2)), 1.0)
    z = np.exp(1j * np.linspace(0.3, 1.5, 400))
    var = rng.uniform(0.5, 2.0, size=(z.size, 3, 2)) * 1e-3
    sel = model.oscillatory
    CV = (model.C @ model.V)[:, sel]
    L = model.modal_inputs[sel]
    cols = []
    for a, mu in enumerate(model.mu[sel]):
        term = CV[None, :, a, None] * L[None, a, None, :] / (z - mu)[:, None, None]
        twin = np.conj(CV[None, :, a, None] * L[None, a, None, :]) / (z - np.conj(mu))[
            :, None, None]
        for c in (term + twin, 1j * (term - twin)):
            c = c * np.sqrt(2.0 / var)
            cols.append(np.concatenate([c.real.ravel(), c.imag.ravel()]))
    G = np.array(cols) @ np.array(cols).T
    inv = np.linalg.inv(G)
    want = [np.linalg.inv(inv[2 * a:2 * a + 2, 2 * a:2 * a + 2])[0, 0]
            for a in range(sel.size)]
    got = whitening.mode_snr2(model, z, var, max_lines=z.size)
    np.testing.assert_allclose(got, want, rtol=1e-9)


def test_quadrature_lines_take_every_line_near_a_pole_and_weigh_the_rest():
    z = np.exp(1j * np.linspace(0.1, 3.0, 5000))
    mu = np.array([0.999 * z[1234]])
    index, weight = whitening.quadrature_lines(z, mu, 500)
    assert 450 <= index.size <= 550
    assert set(range(1230, 1239)) <= set(index.tolist())
    assert np.all(np.diff(index) > 0)
    assert np.sum(weight) == pytest.approx(5000, rel=0.02)
    all_index, all_weight = whitening.quadrature_lines(z[:400], mu, 500)
    np.testing.assert_array_equal(all_index, np.arange(400))
    np.testing.assert_array_equal(all_weight, 1.0)


def test_noise_levels_of_outputs_sharing_a_name_are_all_reported():
    from types import SimpleNamespace

    from automodal.result import NoiseInfo, unique_labels

    assert unique_labels(["a", "b", "a"]) == ["a #1", "b", "a #3"]
    assert unique_labels(["x", "y"]) == ["x", "y"]
    # a label that is another channel's own name: every name takes its position
    assert unique_labels(["a", "a #1", "a"]) == ["a #1", "a #1 #2", "a #3"]
    estimate = SimpleNamespace(output_level=[0.01, 0.02, 0.03], source="data",
                               n_averages=None, assumptions=[])
    info = NoiseInfo.from_estimate(estimate, ["acc", "acc", "ref"])
    assert info.output_level == {"acc #1": 0.01, "acc #2": 0.02, "ref": 0.03}
