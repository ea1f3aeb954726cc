"""The noise model of FRF data (automodal/core/noise.py) against known noise.

A small generator of its own: the receptance of a 3-mode system with two outputs, one or two
inputs, on 800 lines (about 6 lines per half-power bandwidth at the first mode), and each noise
kind with a fixed seed: additive (std = level x RMS of the entry), proportional (std = level x |H|),
plain averages of records, and H1 from records of random force with the exact noise std of the
estimate for the force that was drawn.

The metric: per FRF entry, the ratio of the RMS over lines of the estimated std to that of the true
std must lie in [0.8, 1.25]; the line-wise shape is checked on the 10 % strongest and the 10 %
weakest lines of each entry (the median ratio of estimated to true std in each group in
[0.8, 1.25]: a proportional noise found flat, or a floor found proportional, fails it).
"""

from __future__ import annotations

import numpy as np
import pytest

from automodal.core import noise

N_LINES = 800
LO, HI = (0.8, 1.25)


# ------------------------------------------------------------------------------ generator


def modal_frf(n_in: int = 1, n_lines: int = N_LINES) -> np.ndarray:
    """Receptance of 3 modes (8, 17, 29 Hz, 2 % damping), 2 outputs, ``n_in`` inputs."""
    f = np.linspace(0.5, 40.0, n_lines)
    s = 2j * np.pi * f
    fn = np.array([8.0, 17.0, 29.0])
    zeta = 0.02
    lam = -zeta * 2 * np.pi * fn + 1j * 2 * np.pi * fn * np.sqrt(1 - zeta**2)
    phi = np.array([[1.0, 0.8, -0.6], [0.5, -1.0, 0.9], [0.7, 0.3, 1.0]])  # (dof, mode)
    out, inp = [0, 1], [0, 2][:n_in]
    H = np.zeros((n_lines, 2, n_in), complex)
    for r in range(3):
        res = np.outer(phi[out, r], phi[inp, r]) / (2j * lam[r].imag)
        H += res[None] / (s[:, None, None] - lam[r]) - res.conj()[None] / (
            s[:, None, None] - lam[r].conj()
        )
    return H


def cnormal(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """Circular complex Gaussian of unit variance ``E |z|^2 = 1``."""
    return (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) / np.sqrt(2.0)


def additive(H: np.ndarray, level: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    sig = (
        level
        * np.sqrt(np.mean(np.abs(H) ** 2, axis=0, keepdims=True))
        * np.ones(H.shape)
    )
    return H + sig * cnormal(np.random.default_rng(seed), H.shape), sig


def proportional(
    H: np.ndarray, level: float, seed: int
) -> tuple[np.ndarray, np.ndarray]:
    sig = level * np.abs(H)
    return H + sig * cnormal(np.random.default_rng(seed), H.shape), sig


def h1_test(H: np.ndarray, level: float, n_rec: int, seed: int):
    """H1 from ``n_rec`` records of random force; (H1, coherence, per-record ratios or None, "
    "true std)."""
    rng = np.random.default_rng(seed)
    N, ny, nu = H.shape
    U = cnormal(rng, (n_rec, N, nu))
    Y = np.einsum("fij,rfj->rfi", H, U)
    s_out = level * np.sqrt(np.mean(np.abs(Y) ** 2, axis=(0, 1)))
    Y = Y + s_out * cnormal(rng, (n_rec, N, ny))
    Syu = np.einsum("rfi,rfj->fij", Y, U.conj()) / n_rec
    Suu = np.einsum("rfi,rfj->fij", U, U.conj()) / n_rec
    Syy = np.einsum("rfi,rfi->fi", Y, Y.conj()).real / n_rec
    H1 = np.transpose(
        np.linalg.solve(np.transpose(Suu, (0, 2, 1)), np.transpose(Syu, (0, 2, 1))),
        (0, 2, 1),
    )
    coh = np.real(np.einsum("fij,fjk,fik->fi", H1, Suu, H1.conj())) / Syy
    coh = np.clip(coh, 0, 1)[:, :, None] * np.ones((1, 1, nu))
    inv_diag = np.real(np.einsum("fjj->fj", np.linalg.inv(Suu)))
    sig = s_out[None, :, None] * np.sqrt(inv_diag[:, None, :] / n_rec)
    rec = Y[..., None] / U[:, :, None, :] if nu == 1 else None
    return H1, coh, rec, sig


# ------------------------------------------------------------------------------ metric


def rms_ratio(var: np.ndarray, sig: np.ndarray) -> np.ndarray:
    """Per entry: RMS over lines of the estimated std over that of the true std."""
    return np.sqrt(np.mean(var, axis=0) / np.mean(sig**2, axis=0))


def assert_within(var: np.ndarray, sig: np.ndarray) -> None:
    r = rms_ratio(var, sig)
    assert np.all((r >= LO) & (r <= HI)), (
        f"estimated/true RMS std per entry: {np.round(r, 3)}"
    )


def assert_shape_follows(var: np.ndarray, sig: np.ndarray, H: np.ndarray) -> None:
    """Median est/true std on the strongest and on the weakest 10 % of each entry's lines."""
    mag = np.abs(H)
    for i in range(H.shape[1]):
        for j in range(H.shape[2]):
            order = np.argsort(mag[:, i, j])
            k = max(1, H.shape[0] // 10)
            for name, idx in (("weakest", order[:k]), ("strongest", order[-k:])):
                r = float(np.median(np.sqrt(var[idx, i, j]) / sig[idx, i, j]))
                assert LO <= r <= HI, (
                    f"entry ({i}, {j}), {name} lines: median est/true std {r:.3f}"
                )


# ------------------------------------------------------------------------------ records


def test_records_mean_variance_within_20_percent() -> None:
    H = modal_frf(n_in=2)
    sig = 0.03 * np.abs(H) + 0.01 * np.sqrt(np.mean(np.abs(H) ** 2, axis=0))
    R = 8
    rec = H[None] + np.sqrt(R) * sig[None] * cnormal(
        np.random.default_rng(1), (R, *H.shape)
    )
    frf = rec.mean(axis=0)
    assert noise.records_are_mean(rec, frf)
    est = noise.estimate_noise(frf, records=rec, coherence=np.full(H.shape, 0.5))
    assert est.source == "records"
    assert_within(est.variance, sig)
    assert_shape_follows(est.variance, sig, H)


def test_ratio_records_of_h1() -> None:
    H1, _coh, rec, sig = h1_test(modal_frf(n_in=1), 0.05, 16, seed=2)
    assert not noise.records_are_mean(rec, H1)
    assert_within(noise.ratio_records_variance(rec, H1), sig)
    est = noise.estimate_noise(H1, records=rec)
    assert est.source == "records" and "ratio" in est.assumptions[0]
    assert_within(est.variance, sig)


@pytest.mark.parametrize("n_rec", [4, 8, 32])
def test_mean_of_ratio_records_is_not_as_precise_as_h1(n_rec: int) -> None:
    """The record bootstrap averages records: under random force that is a noisier
    estimator than H1 (the pipeline then resamples as without records)."""
    H1, _coh, rec, sig = h1_test(modal_frf(n_in=1), 0.05, n_rec, seed=7 + n_rec)
    assert not noise.mean_as_precise(rec, sig**2)


def test_mean_of_plain_records_is_as_precise() -> None:
    H = modal_frf(n_in=2)
    sig = 0.03 * np.abs(H)
    R = 6
    rec = H[None] + np.sqrt(R) * sig[None] * cnormal(np.random.default_rng(4), (R, *H.shape))
    assert noise.mean_as_precise(rec, sig**2)
    assert not noise.mean_as_precise(rec[:1], sig**2)


# ------------------------------------------------------------------------------ coherence


@pytest.mark.parametrize("n_in, n_rec", [(1, 8), (1, 32), (2, 16), (2, 8)])
def test_coherence_law_within_20_percent(n_in: int, n_rec: int) -> None:
    H1, coh, _rec, sig = h1_test(modal_frf(n_in=n_in), 0.05, n_rec, seed=3 + n_rec)
    est = noise.estimate_noise(H1, coherence=coh, n_averages=n_rec)
    assert est.source == "coherence" and est.n_averages == n_rec
    assert_within(est.variance, sig)
    assert_shape_follows(est.variance, sig, H1)


@pytest.mark.parametrize("n_in, stated, conflict", [
    (1, 8, False), (2, 16, False), (1, 40, True), (2, 4, True), (2, 40, True)])
def test_a_stated_number_of_averages_is_checked_against_the_data(
        n_in: int, stated: int, conflict: bool) -> None:
    """A file's number of averages is used as given, but one whose law's variance differs
    from what the FRF's own scatter shows by more than ``AVERAGES_AGREEMENT`` (a std off by
    20 %) is named in ``conflicts``, with the number the data imply."""
    true = 8 if stated in (8, 40) else 16
    H1, coh, _rec, _sig = h1_test(modal_frf(n_in=n_in), 0.05, true, seed=5 + stated)
    est = noise.estimate_noise(H1, coherence=coh, n_averages=stated)
    assert est.n_averages == stated
    assert bool(est.conflicts) is conflict
    if conflict:
        implied = float(est.conflicts[0].split("(as ")[1].split()[0])
        assert 0.8 * true <= implied <= 1.25 * true


def test_a_wrong_number_of_averages_is_a_warning_of_the_run(tmp_path) -> None:
    """The pipeline says so among the run's warnings."""
    from dataclasses import replace

    from automodal.frfdata import FRFData
    from automodal.pipeline import prepare
    from automodal.settings import Settings

    H1, coh, _rec, _sig = h1_test(modal_frf(n_in=1), 0.05, 8, seed=3)
    data = FRFData(frequency=np.linspace(1.0, 100.0, H1.shape[0]), frf=H1,
                   quantity="displacement", coherence=coh)
    warnings: list[str] = []
    prepare(replace(data, attributes={"n_averages": 40}), Settings(), warnings)
    assert any("number of averages, 40" in w for w in warnings)
    warnings = []
    prepare(replace(data, attributes={"n_averages": 8}), Settings(), warnings)
    assert not any("number of averages" in w for w in warnings)


def test_coherence_takes_averages_from_records() -> None:
    H1, coh, rec, sig = h1_test(modal_frf(n_in=1), 0.02, 16, seed=7)
    est = noise.estimate_noise(H1, coherence=coh, records=rec)
    assert est.source == "coherence" and est.n_averages == 16
    assert_within(est.variance, sig)


def test_coherence_calibrates_unknown_averages() -> None:
    H1, coh, _, sig = h1_test(modal_frf(n_in=2), 0.05, 16, seed=8)
    est = noise.estimate_noise(H1, coherence=coh)
    assert est.source == "coherence"
    assert 12 <= est.n_averages <= 21
    assert any("calibrated" in a for a in est.assumptions)
    assert any("uncorrelated" in a for a in est.assumptions)
    assert_within(est.variance, sig)


@pytest.mark.parametrize("seed", [0, 3])
def test_coherence_calibrates_averages_on_a_band_of_noise_alone(seed: int) -> None:
    """A band where the FRF is far below the noise (an accelerance's low end): H1 then
    regresses noise on the realized force, and its coherence law is heavy tailed from line
    to line. The calibrated ``n_d`` is the whole band's, and the variance right (a ratio
    against the smooth data-alone model had given ``n_d`` 21-30 for 8 and half the std)."""
    H = modal_frf(n_in=2, n_lines=1600)
    H[:600] *= 1e-4
    H1, coh, _, sig = h1_test(H, 0.05, 8, seed=seed)
    est = noise.estimate_noise(H1[:600], coherence=coh[:600])
    assert 7.0 <= est.n_averages <= 9.5
    assert_within(est.variance, sig[:600])


@pytest.mark.parametrize("step", [20, 40])
def test_coherence_of_zero_on_some_lines_leaves_the_calibration(step: int) -> None:
    """A coherence of 0 (no law: ``U = |H|^2 / eps``) on one line in ``step`` must not
    send the windows around it, and the trimmed mean after them, to 0 (it gave ``n_d``
    1.8e18 and every variance at the precision floor); nor does a stretch of coherence 1."""
    H1, coh, _, sig = h1_test(modal_frf(n_in=2, n_lines=1600), 0.05, 8, seed=1)
    coh = coh.copy()
    coh[::step] = 0.0
    coh[100:130] = 1.0
    est = noise.estimate_noise(H1, coherence=coh)
    assert 7.0 <= est.n_averages <= 9.5
    ok = (coh > 0) & (coh < 1)
    r = np.sqrt(np.mean(est.variance[ok]) / np.mean(sig[ok] ** 2))
    assert LO <= r <= HI


def test_coherence_needs_more_averages_than_inputs() -> None:
    H = modal_frf(n_in=2)
    with pytest.raises(ValueError, match="averages"):
        noise.coherence_variance(H, np.full(H.shape, 0.9), 2)


# ------------------------------------------------------------------------------ data alone


@pytest.mark.parametrize("level", [0.01, 0.1])
def test_data_alone_additive(level: float) -> None:
    H = modal_frf(n_in=2)
    frf, sig = additive(H, level, seed=11)
    est = noise.estimate_noise(frf)
    assert est.source == "data"
    assert_within(est.variance, sig)
    assert_shape_follows(est.variance, sig, H)
    np.testing.assert_allclose(est.level, level, rtol=0.2)


@pytest.mark.parametrize("level", [0.01, 0.1])
def test_data_alone_proportional(level: float) -> None:
    H = modal_frf(n_in=2)
    frf, sig = proportional(H, level, seed=12)
    est = noise.estimate_noise(frf)
    assert_within(est.variance, sig)
    assert_shape_follows(est.variance, sig, H)
    # found proportional: the floor explains little, sqrt(b) is the level
    np.testing.assert_allclose(np.sqrt(est.proportional), level, rtol=0.2)


def test_data_alone_mixed_floor_and_proportional() -> None:
    H = modal_frf(n_in=1)
    rms = np.sqrt(np.mean(np.abs(H) ** 2, axis=0, keepdims=True))
    sig = np.sqrt((0.005 * rms) ** 2 + (0.03 * np.abs(H)) ** 2)
    frf = H + sig * cnormal(np.random.default_rng(13), H.shape)
    est = noise.estimate_noise(frf)
    assert_within(est.variance, sig)
    assert_shape_follows(est.variance, sig, H)


def test_data_alone_h1() -> None:
    H1, _, _, sig = h1_test(modal_frf(n_in=2), 0.05, 16, seed=14)
    var, _a, _b = noise.data_variance(H1)
    assert_within(var, sig)


def test_local_polynomial_is_unbiased_on_white_noise() -> None:
    rng = np.random.default_rng(15)
    e = cnormal(rng, (20000, 1, 1)) * 0.3
    local, dof, lev = noise.local_polynomial_variance(e, half_width=5, degree=6)
    assert dof == 4
    assert abs(local.mean() / 0.09 - 1) < 0.03
    np.testing.assert_allclose(lev.sum(), 1.0)


# ------------------------------------------------------------------------------ exact data, shapes


@pytest.mark.parametrize("dtype", [np.complex128, np.complex64])
def test_exact_data_gives_tiny_finite_variance(dtype: type) -> None:
    H = modal_frf(n_in=2).astype(dtype)
    est = noise.estimate_noise(H)
    v = est.variance
    assert v.shape == H.shape and v.dtype == np.float64
    assert np.all(np.isfinite(v)) and np.all(v > 0)
    rel = np.sqrt(v.mean(axis=0)) / np.sqrt(np.mean(np.abs(H) ** 2, axis=0))
    assert np.all(rel < (1e-3 if dtype is np.complex64 else 1e-6)), rel
    assert np.all(v >= noise.precision_floor(H))
    w = H / np.sqrt(v)  # whitening stays finite
    assert np.all(np.isfinite(w))


def test_zero_and_constant_entries() -> None:
    H = modal_frf(n_in=1)
    H[:, 1, 0] = 0.0
    est = noise.estimate_noise(H)
    assert np.all(np.isfinite(est.variance)) and np.all(est.variance > 0)
    assert np.all(np.isfinite(est.level))


def test_estimate_shapes_and_summary() -> None:
    H = modal_frf(n_in=2)
    frf, _sig = additive(H, 0.02, seed=16)
    est = noise.estimate_noise(frf)
    assert est.variance.shape == (N_LINES, 2, 2)
    assert est.std.shape == (N_LINES, 2, 2)
    assert est.level.shape == (2, 2) and est.output_level.shape == (2,)
    assert est.floor.shape == (2, 2) and est.proportional.shape == (2, 2)
    assert np.all(est.floor >= 0) and np.all(est.proportional >= 0)
    assert est.assumptions


def test_bad_shapes_are_refused() -> None:
    H = modal_frf(n_in=1)
    with pytest.raises(ValueError):
        noise.estimate_noise(H[:, :, 0])
    with pytest.raises(ValueError):
        noise.estimate_noise(H, records=np.ones((3, 10, 2, 1), complex))
    with pytest.raises(ValueError):
        noise.estimate_noise(H, coherence=np.ones((10, 2, 1)))


def test_coherence_of_one_record_per_input_is_ignored() -> None:
    """H1 of one hammer hit has coherence 1 everywhere: the data alone give the noise."""
    H = modal_frf(n_in=1)
    est = noise.estimate_noise(H, coherence=np.ones(H.shape), records=H[None])
    assert est.source == "data" and any("coherence ignored" in a for a in est.assumptions)
    est = noise.estimate_noise(H, coherence=np.ones(H.shape))
    assert est.source == "data"


def test_averages_from_attributes() -> None:
    assert noise.averages_from_attributes({"N_Averages": 32}) == 32.0
    assert noise.averages_from_attributes({"averages": np.array([16])}) == 16.0
    assert noise.averages_from_attributes({"operator": "x"}) is None
    assert noise.averages_from_attributes({"n_averages": "many"}) is None
    assert noise.averages_from_attributes({"n_averages": 1e9}) == 1e9
    assert noise.averages_from_attributes({"n_averages": 1e200}) is None  # overflowed later


def test_a_line_far_above_the_others_gives_no_overflow_warning() -> None:
    """A line ``1e170`` times the median power (drawn by the readers' property tests): its
    weight underflows to zero, silently, and the fit stays finite."""
    import warnings

    rng = np.random.default_rng(0)
    h = rng.uniform(0.5, 2.0, 200)
    h[50] = 1e170
    v = (1.0 + 0.5 * h) * rng.chisquare(8, 200) / 8
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        a, b = noise._fit_one(v, h, 2.0, 0.98, 30)
    assert np.isfinite(a) and np.isfinite(b) and a >= 0 and b >= 0
