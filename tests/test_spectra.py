"""Time-series input: spectral estimates, the /time reader, and identification end to end.

Time responses of a known 5-DOF chain are simulated by an exact (zero-order-hold)
discretisation of :func:`automodal.core.simulate.state_space`, so the estimates can be
compared with the exact discrete-time FRF ``C (z I - Ad)^-1 Bd + D``.
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.linalg
import scipy.signal

from automodal.core import simulate as sim
from automodal.core import spectra
from automodal.core.from_time import frfdata_from_time
from automodal.errors import InputError
from automodal.frfdata import FRFData
from automodal.io.time_file import read_time, write_time
from automodal.pipeline import identify
from automodal.settings import Settings
from automodal.timedata import TimeSeries

FS = 128.0
N_SAMPLES = 2**16
REALDATA = Path(__file__).parents[1].parent / "shared" / "realdata"

# ------------------------------------------------------------------------------ helpers


def chain5() -> sim.MechanicalSystem:
    """5-DOF chain, modes 4.5-30.5 Hz, damping 1.35-2 %."""
    return sim.damp(sim.chain(5, stiffness=1e4), zeta=0.02)


def discretise(
    system: sim.MechanicalSystem,
    inputs: list[int] | None,
    quantity: str = "displacement",
    fs: float = FS,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation (all DOFs as outputs of ``quantity``)."""
    A, B, C, D = sim.state_space(system, None, inputs, quantity)
    n, m = A.shape[0], B.shape[1]
    E = scipy.linalg.expm(np.block([[A, B], [np.zeros((m, n + m))]]) / fs)
    return E[:n, :n], E[:n, n:], C, D


def respond(model: tuple, u: np.ndarray) -> np.ndarray:
    """Response of the discrete model to the input samples ``u`` (zero initial state)."""
    _, y, _ = scipy.signal.dlsim(model + (1.0,), u)
    return y


def exact_frf(model: tuple, freq: np.ndarray, fs: float = FS) -> np.ndarray:
    """``C (z I - Ad)^-1 Bd + D`` at ``z = exp(j 2 pi f / fs)``."""
    Ad, Bd, C, D = model
    z = np.exp(2j * np.pi * freq / fs)
    inv = np.linalg.inv(z[:, None, None] * np.eye(Ad.shape[0]) - Ad)
    return np.einsum("ij,fjk,kl->fil", C, inv, Bd) + D


def found_within(true_hz: np.ndarray, modes: list, tol: float = 0.01) -> np.ndarray:
    """For each true frequency, whether a physical mode lies within ``tol``."""
    f = np.array([m.frequency_hz for m in modes if m.physical])
    return np.array([f.size > 0 and np.min(np.abs(f / t - 1)) < tol for t in true_hz])


@pytest.fixture(scope="module")
def truth() -> sim.Modes:
    return sim.exact_modes(chain5())


@pytest.fixture(scope="module")
def random_test() -> tuple[TimeSeries, tuple]:
    """Random force at DOF 5, five displacement outputs, no noise."""
    model = discretise(chain5(), [4])
    u = np.random.default_rng(1).standard_normal((N_SAMPLES, 1))
    return TimeSeries(respond(model, u), u, FS), model


@pytest.fixture(scope="module")
def ambient_test() -> tuple[TimeSeries, tuple]:
    """White forces at every DOF, unmeasured; accelerations with 5 % white sensor noise."""
    model = discretise(chain5(), None, "acceleration")
    f = np.random.default_rng(2).standard_normal((N_SAMPLES, 5))
    y = respond(model, f)
    y += 0.05 * y.std(axis=0) * np.random.default_rng(3).standard_normal(y.shape)
    return TimeSeries(y, None, FS, attributes={"quantity": "acceleration"}), model


@pytest.fixture(scope="module")
def impact_test() -> tuple[TimeSeries, tuple]:
    """Six hammer hits at DOF 5, separate 4 s records (the response has not died out)."""
    model = discretise(chain5(), [4])
    rng = np.random.default_rng(3)
    n, at = 512, 20
    u, y = [], []
    for _ in range(6):
        hit = np.zeros((n, 1))
        hit[at : at + 3, 0] = rng.uniform(50, 100) * np.sin(np.pi * np.arange(1, 4) / 4)
        hit[:, 0] += 0.01 * rng.standard_normal(n)  # force noise outside the pulse
        u.append(hit)
        y.append(respond(model, hit))
    ts = TimeSeries(np.vstack(y), np.vstack(u), FS, attributes={"quantity": "displacement"})
    return ts, model


# ----------------------------------------------------------------------- segment choice


def test_choose_segment_rule():
    # 16 averages at 50 % overlap where the record allows it
    assert spectra.choose_segment(N_SAMPLES, FS) == 4096
    assert spectra.segment_count(N_SAMPLES, 4096) == 31
    assert spectra.choose_segment(61440, 256.0) == 4096
    # short record: averages given up for resolution, never below 8
    L = spectra.choose_segment(4000, 100.0)
    assert L == 512 and spectra.segment_count(4000, L) >= 8
    # long record: capped line budget; an asked resolution wins
    assert spectra.choose_segment(10**7, 1000.0) == 16384
    assert spectra.choose_segment(10**7, 1000.0, resolution_hz=0.01) == 131072
    # very short record: still a power of two with 3 segments
    assert spectra.choose_segment(40, 1.0) == 16
    with pytest.raises(ValueError):
        spectra.choose_segment(20, 1.0)


def test_segment_starts_and_count():
    st = spectra.segment_starts(1000, 100, 0.5)
    assert st[0] == 0 and np.all(np.diff(st) == 50) and st[-1] + 100 <= 1000
    assert st.size == spectra.segment_count(1000, 100, 0.5) == 19
    assert spectra.segment_count(50, 100) == 0


# --------------------------------------------------------------------------------- H1


def test_h1_matches_exact_frf(random_test, truth):
    ts, model = random_test
    L = spectra.choose_segment(ts.n_samples, FS)
    freq, H, coh, rec = spectra.h1_estimate(ts.outputs, ts.inputs, FS, L)
    assert H.shape == (L // 2 + 1, 5, 1) and coh.shape == H.shape
    assert rec.shape[1:] == H.shape and rec.shape[0] == spectra.segment_count(N_SAMPLES, L) // 3
    k = (freq > 0) & (freq < 50)
    Hx = exact_frf(model, freq[k])
    err = np.abs(H[k] - Hx) / np.abs(Hx)
    assert np.median(err) < 2e-3
    assert np.median(coh[k]) > 0.999
    for f0, z0 in zip(truth.frequency_hz, truth.damping_ratio):
        near = np.abs(freq[k] - f0) <= z0 * f0  # the half-power band
        assert near.any()
        assert np.max(err[near]) < 0.08, (f0, np.max(err[near]))  # Hann leakage bias only
        assert np.min(coh[k][near]) > 0.9
    # the records average to (nearly) H away from the resonances
    mean = rec.mean(axis=0)[k]
    away = np.min(np.abs(freq[k][:, None] - truth.frequency_hz[None, :]), axis=1) > 1.0
    assert np.median(np.abs(mean[away] - H[k][away]) / np.abs(H[k][away])) < 0.01


def test_h1_two_inputs_matrix_form_and_multiple_coherence():
    model = discretise(chain5(), [0, 4])
    u = np.random.default_rng(4).standard_normal((2**14, 2))
    y = respond(model, u)
    freq, H, coh, rec = spectra.h1_estimate(y, u, FS, 1024, segments_per_record=4)
    assert H.shape == (513, 5, 2) and rec.shape == (7, 513, 5, 2)  # 31 segments // 4
    k = (freq > 1) & (freq < 40)
    Hx = exact_frf(model, freq[k])
    assert np.median(np.abs(H[k] - Hx) / np.abs(Hx)) < 0.02
    assert np.median(coh[k]) > 0.99 and np.all(coh <= 1) and np.all(coh >= 0)
    assert np.array_equal(coh[..., 0], coh[..., 1])  # one multiple coherence per output


def test_h1_output_noise_lowers_coherence_not_h1(random_test):
    ts, model = random_test
    y = ts.outputs + 0.3 * ts.outputs.std(axis=0) * np.random.default_rng(5).standard_normal(
        ts.outputs.shape
    )
    freq, H, coh, _ = spectra.h1_estimate(y, ts.inputs, FS, 2048)
    k = (freq > 1) & (freq < 40)
    Hx = exact_frf(model, freq[k])
    assert np.median(coh[k]) < 0.98
    ratio = np.median((H[k] / Hx).real)  # the complex ratio: |H| alone is biased up by noise
    assert abs(ratio - 1) < 0.02  # H1 is not biased by output noise


# ------------------------------------------------------------- correlation, half spectra


def test_cross_correlation_is_the_exact_unbiased_sum():
    rng = np.random.default_rng(6)
    y = rng.standard_normal((9000, 3))
    R = spectra.cross_correlation(y, [2, 0], 40)
    yc = y - y.mean(axis=0)
    n = y.shape[0]
    for tau in (0, 1, 17, 39):
        direct = yc[tau:].T @ yc[: n - tau, [2, 0]] / (n - tau)
        np.testing.assert_allclose(R[tau], direct, rtol=1e-10, atol=1e-12)


def test_record_correlations_split_the_sum_by_stretch():
    rng = np.random.default_rng(7)
    y = rng.standard_normal((9001, 3))
    m, n_rec = 40, 7
    Rr = spectra.record_correlations(y, [2, 0], m, n_rec)
    assert Rr.shape == (n_rec, m, 3, 2)
    np.testing.assert_allclose(Rr.mean(axis=0), spectra.cross_correlation(y, [2, 0], m),
                               rtol=1e-12, atol=1e-14)
    yc = y - y.mean(axis=0)
    n = y.shape[0]
    edges = (np.arange(n_rec + 1) * n) // n_rec
    for b in (0, 3, n_rec - 1):  # the outputs reach into the next stretch, not past the end
        for tau in (0, 1, 39):
            t = np.arange(edges[b], min(edges[b + 1], n - tau))
            direct = yc[t + tau].T @ yc[t][:, [2, 0]] * n_rec / (n - tau)
            np.testing.assert_allclose(Rr[b, tau], direct, rtol=1e-10, atol=1e-12)
    freq, G = spectra.half_spectra(y, [2, 0], 10.0, m)
    freq_r, Gr = spectra.half_spectrum_records(y, [2, 0], 10.0, m, n_rec)
    assert np.array_equal(freq, freq_r)
    np.testing.assert_allclose(Gr.mean(axis=0), G, rtol=1e-12, atol=1e-14)
    freq_k, Gk = spectra.half_spectrum_records(y, [2, 0], 10.0, m, n_rec, n_lines=9)
    assert np.array_equal(freq_k, freq[:9]) and np.array_equal(Gk, Gr[:, :9])
    for bad in (1, 9001 // m + 1):
        with pytest.raises(ValueError, match="n_records"):
            spectra.record_correlations(y, [2, 0], m, bad)


def test_half_spectrum_records_measure_the_error_of_the_half_spectra():
    """Over 16 independent ambient records of the chain, the half spectra's variance near
    the modes is what each record's 48 stretches say (the variance of their mean) within
    40 % (measured: 0.79 of it); the data-alone noise model, which takes neighbouring
    lines as independent, sees under a tenth of it (measured: 0.002; the errors are smooth
    across lines)."""
    from automodal.core.noise import estimate_noise, records_variance

    model = discretise(chain5(), None, "acceleration")
    L, n, K = 256, 16384, 16
    G, by_records, alone = [], [], []
    for k in range(K):
        y = respond(model, np.random.default_rng(100 + k).standard_normal((n, 5)))
        y += 0.05 * y.std(axis=0) * np.random.default_rng(200 + k).standard_normal(y.shape)
        freq, rec = spectra.half_spectrum_records(y, [0, 4], FS, L, 48)
        G.append(rec.mean(axis=0))
        by_records.append(records_variance(rec))
        alone.append(estimate_noise(G[-1][1:]).variance)
    G = np.array(G)
    actual = np.sum(np.abs(G - G.mean(axis=0)) ** 2, axis=0) / (K - 1)
    near = np.zeros(freq.size, bool)
    for f0 in sim.exact_modes(chain5()).frequency_hz:
        near |= np.abs(freq - f0) < 1.0
    ratio = np.median((np.mean(by_records, axis=0) / actual)[near])
    assert 0.6 < ratio < 1.4, ratio
    assert np.median((np.mean(alone, axis=0) / actual[1:])[near[1:]]) < 0.1


def test_half_spectra_have_the_state_space_form(ambient_test, truth):
    ts, (Ad, Bd, C, D) = ambient_test
    refs = [0, 4]
    L = 4096
    freq, G = spectra.half_spectra(ts.outputs, refs, FS, L)
    assert G.shape == (L // 2 + 1, 5, 2)
    # exact: R(tau) = C Ad^(tau-1) (Ad P C_ref^T + Bd D_ref^T) for tau >= 1 (P the state
    # covariance; the white force and sensor noise enter R(0) only); the window rho^tau
    # turns the one-sided sum into Δt [R(0)/2 + C (zI - rho Ad)^-1 rho (Ad P C_ref^T + ...)]
    P = scipy.linalg.solve_discrete_lyapunov(Ad, Bd @ Bd.T)
    rho = np.exp(-spectra.exponential_decay(L, FS) / FS)
    k = (freq > 1) & (freq < 40)
    z = np.exp(2j * np.pi * freq[k] / FS)
    inv = np.linalg.inv(z[:, None, None] * np.eye(Ad.shape[0]) - rho * Ad)
    K = Ad @ P @ C[refs].T + Bd @ D[refs].T
    R0 = C @ P @ C[refs].T + D @ D[refs].T
    Gx = (np.einsum("ij,fjk,kl->fil", C, inv, rho * K) + 0.5 * R0) / FS
    peaks = np.abs(Gx).sum(axis=(1, 2)) > np.percentile(np.abs(Gx).sum(axis=(1, 2)), 90)
    rel = np.linalg.norm(G[k] - Gx, axis=(1, 2)) / np.linalg.norm(Gx, axis=(1, 2))
    assert np.median(rel[peaks]) < 0.25  # estimation error of a 512 s record
    # peaks of the half spectra at the true frequencies (within 2 %: a noisy estimate)
    mag = np.log(np.abs(G[k]).sum(axis=(1, 2)))
    idx, _ = scipy.signal.find_peaks(mag, prominence=0.5)
    fk = freq[k][idx]
    assert fk.size == truth.frequency_hz.size, fk
    for f0 in truth.frequency_hz:
        assert np.min(np.abs(fk - f0)) < 0.02 * f0, (f0, fk)


def test_undo_exponential_window_inverts_the_pole_shift():
    lam = -0.02 * 2 * np.pi * 5 + 1j * 2 * np.pi * 5 * np.sqrt(1 - 0.02**2)
    a = 0.7
    shifted = lam - a
    f1, z1 = np.abs(shifted) / (2 * np.pi), -shifted.real / np.abs(shifted)
    f0, z0 = spectra.undo_exponential_window(f1, z1, a)
    assert np.isclose(f0, 5.0) and np.isclose(z0, 0.02)


def test_choose_references_sees_all_modes_and_skips_duplicates(ambient_test):
    ts, _ = ambient_test
    y = ts.outputs
    noise = np.random.default_rng(7).standard_normal(y.shape[0])
    # channel 5 is pure noise, channel 6 a copy of channel 0 at another gain
    x = np.column_stack([y, noise, 3.0 * y[:, 0]])
    refs = spectra.choose_references(x, FS)
    assert 1 <= len(refs) <= 3 and len(set(refs)) == len(refs)
    assert 5 not in refs
    assert not {0, 6} <= set(refs)
    assert spectra.choose_references(x, FS, max_refs=1) == refs[:1]


# ------------------------------------------------------------------- end to end (pipeline)


def test_identify_random_excitation(random_test, truth):
    ts, _ = random_test
    data, info = frfdata_from_time(ts)
    assert info["excitation"] == "random" and info["nperseg"] == 4096
    assert data.frequency[0] > 0 and data.frequency[-1] <= FS / 2.56 + 1e-9
    assert data.coherence is not None and data.records is not None
    assert data.quantity == "displacement" and info["quantity_assumed"]
    result = identify(data, Settings(n_bootstrap=20, jobs=1))
    assert found_within(truth.frequency_hz, result.modes).all()


def test_identify_operational(ambient_test, truth):
    ts, _ = ambient_test
    data, info = frfdata_from_time(ts)
    assert data.attributes["analysis"] == "operational"
    assert info["references"] and data.input_names == [f"y{i + 1}" for i in info["references"]]
    assert data.coherence is None
    # one record per stretch of at least max-lag samples, their mean the half spectra
    assert data.records.shape == (info["n_records"],) + data.frf.shape
    assert info["n_records"] == min(48, ts.n_samples // info["nperseg"]) >= 2  # small test
    np.testing.assert_allclose(data.records.mean(axis=0), data.frf,
                               atol=1e-12 * np.abs(data.frf).max())
    result = identify(data, Settings(n_bootstrap=20, jobs=1))
    assert found_within(truth.frequency_hz, result.modes).all()
    # the bootstrap resamples the records; no likelihood refinement (correlated line errors)
    assert result.noise.source == "records"
    assert any(w.startswith(f"bootstrap over the {info['n_records']} repeated records")
               for w in result.warnings), result.warnings
    assert all(m.estimator == "bootstrap" for m in result.physical_modes)
    # without its records the same data are still not refined, and the report says why
    bare = FRFData(frequency=data.frequency, frf=data.frf, quantity=data.quantity,
                   attributes=data.attributes)
    result = identify(bare, Settings(n_bootstrap=20, jobs=1))
    assert all(m.estimator == "bootstrap" for m in result.physical_modes)
    assert any("without records" in w for w in result.warnings), result.warnings
    a = info["lag_window_decay_per_s"]
    for f0, z0 in zip(truth.frequency_hz, truth.damping_ratio):
        m = min(result.physical_modes, key=lambda m: abs(m.frequency_hz - f0))
        _, z = spectra.undo_exponential_window(m.frequency_hz, m.damping_ratio, a)
        assert abs(z - z0) < 0.25 * z0, (f0, m.damping_ratio, z, z0)


def test_identify_impact_records(impact_test, truth):
    ts, model = impact_test
    data, info = frfdata_from_time(ts)
    assert info["excitation"] == "impact"
    assert info["hits"] == [512 * i for i in range(6)] and info["nperseg"] == 512
    assert info["exponential_decay_per_s"] > 0  # the 4 s records had not died out
    assert data.records.shape == (6,) + data.frf.shape
    result = identify(data, Settings(n_bootstrap=20, jobs=1))
    a = info["exponential_decay_per_s"]
    for f0, z0 in zip(truth.frequency_hz, truth.damping_ratio):
        m = min(result.physical_modes, key=lambda m: abs(m.frequency_hz - f0))
        f, z = spectra.undo_exponential_window(m.frequency_hz, m.damping_ratio, a)
        assert abs(f / f0 - 1) < 0.01
        assert abs(z - z0) < 0.25 * z0, (f0, m.damping_ratio, z, z0)


def test_double_hits_and_overloads_are_dropped_with_a_warning(impact_test):
    ts, _ = impact_test
    u, y = ts.inputs.copy(), ts.outputs.copy()
    peak = np.max(np.abs(u[512 : 2 * 512]))
    u[512 + 60 : 512 + 63, 0] = 0.4 * peak  # hit 2: the hammer bounced
    y[4 * 512 + 100 : 4 * 512 + 104, 0] = np.max(np.abs(y)) * 1.5  # hit 5: response clipped
    bad = TimeSeries(y, u, ts.sample_rate, attributes={"quantity": "displacement"})
    keep, reasons = spectra.screen_hits(bad.inputs, bad.outputs, np.arange(6) * 512, 512)
    assert keep.tolist() == [True, False, True, True, False, True]
    assert "double hit" in reasons[0] and "hit 2" in reasons[0]
    assert "overload" in reasons[1] and "response 1" in reasons[1]
    # through the input stage (at 128 Hz a bounce is a hit of its own: the overload only)
    clipped = TimeSeries(y, ts.inputs, ts.sample_rate, attributes={"quantity": "displacement"})
    data, info = frfdata_from_time(clipped)
    assert info["dropped_hits"] == 1 and data.records.shape[0] == 5
    assert 4 * 512 + 20 not in info["hits"]
    result = identify(clipped, Settings(n_bootstrap=10, jobs=1))
    assert any("overload" in w for w in result.warnings)
    # the clean test loses nothing
    assert spectra.screen_hits(ts.inputs, ts.outputs, np.arange(6) * 512, 512)[0].all()
    y_all = ts.outputs.copy()
    for k in range(6):
        y_all[512 * k + 100 : 512 * k + 104, 0] = np.max(np.abs(ts.outputs)) * 1.5
    every = TimeSeries(y_all, ts.inputs, ts.sample_rate)
    with pytest.raises(ValueError, match="every hammer hit is unusable"):
        frfdata_from_time(every)


def test_frfdata_from_time_choices_and_refusals(random_test):
    ts, _ = random_test
    short = TimeSeries(ts.outputs[:4096], ts.inputs[:4096], FS, attributes={"quantity": "velocity"})
    data, info = frfdata_from_time(short, nperseg=256)
    assert data.quantity == "velocity" and not info["quantity_assumed"]
    assert info["nperseg"] == 256 and info["n_segments"] == 31
    assert "quantity" not in data.attributes and data.attributes["analysis"] == "h1"
    with pytest.raises(ValueError, match="quantity"):
        frfdata_from_time(TimeSeries(ts.outputs[:4096], None, FS, attributes={"quantity": "jerk"}))
    with pytest.raises(ValueError, match="forces"):
        frfdata_from_time(TimeSeries(ts.outputs[:4096], None, FS), excitation="random")
    dead = ts.outputs[:4096].copy()
    dead[:, 2] = 1.0
    with pytest.raises(ValueError, match="constant"):
        frfdata_from_time(TimeSeries(dead, None, FS))


# ------------------------------------------------------------------------ the /time file


def small_series(with_inputs: bool = True) -> TimeSeries:
    rng = np.random.default_rng(8)
    return TimeSeries(
        outputs=rng.standard_normal((300, 3)),
        inputs=rng.standard_normal((300, 1)) if with_inputs else None,
        sample_rate=512.0,
        output_names=["a", "b", "ü"],
        input_names=["hammer"] if with_inputs else [],
        attributes={"quantity": "acceleration", "structure": "frame", "temperature": 20.5},
    )


@pytest.mark.parametrize("with_inputs", [True, False])
def test_write_read_round_trip(tmp_path, with_inputs):
    ts = small_series(with_inputs)
    path = tmp_path / "t.h5"
    write_time(path, ts)
    back = read_time(path)
    np.testing.assert_array_equal(back.outputs, ts.outputs)
    if with_inputs:
        np.testing.assert_array_equal(back.inputs, ts.inputs)
    else:
        assert back.inputs is None and back.input_names == []
    assert back.sample_rate == ts.sample_rate
    assert back.output_names == ts.output_names and back.input_names == ts.input_names
    assert back.attributes == ts.attributes and back.source == str(path)


def test_read_without_names_or_quantity(tmp_path):
    path = tmp_path / "bare.h5"
    with h5py.File(path, "w") as f:
        f["time/outputs"] = np.random.default_rng(0).standard_normal((100, 2))
        f["time"].attrs["sample_rate"] = 100
    ts = read_time(path)
    assert ts.output_names == ["y1", "y2"] and ts.inputs is None
    assert "quantity" not in ts.attributes and ts.sample_rate == 100.0


def _mutations() -> dict:
    def set_(name, value):
        def m(f):
            del f[name]
            f[name] = value
        return m

    def drop(name):
        def m(f):
            del f[name]
        return m

    def attr(obj, key, value):
        def m(f):
            if value is None:
                del f[obj].attrs[key]
            else:
                f[obj].attrs[key] = value
        return m

    good = np.random.default_rng(9).standard_normal((300, 3))
    nan = good.copy()
    nan[5, 1] = np.nan
    dead = good.copy()
    dead[:, 2] = 0.5
    return {
        "no /time group": (drop("time"), "no /time group"),
        "no outputs": (drop("time/outputs"), "no /time/outputs"),
        "1-D outputs": (set_("time/outputs", good[:, 0]), "must be 2-D"),
        "complex outputs": (set_("time/outputs", good + 1j), "real numbers"),
        "NaN": (set_("time/outputs", nan), "non-finite"),
        "too short": (set_("time/outputs", good[:10]), "too short"),
        "dead channel": (set_("time/outputs", dead), "constant"),
        "inputs length": (set_("time/inputs", good[:200, :1]), "samples"),
        "no sample_rate": (attr("time", "sample_rate", None), "sample_rate"),
        "zero sample_rate": (attr("time", "sample_rate", 0.0), "sample_rate"),
        "text sample_rate": (attr("time", "sample_rate", "fast"), "sample_rate"),
        "names length": (set_("outputs/name", np.array(["a"], dtype=h5py.string_dtype())),
                         "/outputs/name"),
        "newer version": (attr("/", "version", 99), "newer"),
        "unknown quantity": (attr("/", "quantity", "jerk"), "quantity"),
    }


@pytest.mark.parametrize("case", list(_mutations()))
def test_read_time_refuses_bad_files(tmp_path, case):
    mutate, needle = _mutations()[case]
    path = tmp_path / "bad.h5"
    write_time(path, small_series())
    with h5py.File(path, "r+") as f:
        mutate(f)
    with pytest.raises(InputError) as exc:
        read_time(path)
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith(str(path)) and needle in msg, msg


def test_read_time_refuses_missing_and_non_hdf5(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_time(tmp_path / "missing.h5")
    junk = tmp_path / "junk.h5"
    junk.write_text("not hdf5")
    with pytest.raises(InputError, match="not an HDF5 file"):
        read_time(junk)


# ------------------------------------------------------------------------------ realdata


@pytest.mark.realdata
@pytest.mark.skipif(not REALDATA.is_dir(), reason="../shared/realdata is absent")
def test_realdata_weimar_half_spectra():
    """Output-only, setup 1, channels 0-4 at 256 Hz, automatic references. Not yet strict."""
    folder = REALDATA / "weimar_steel_frame"
    y = np.load(folder / "measurement_1" / "measurement_1.npy")[:, :5]
    ref = np.load(folder / "merged_setups.npz", allow_pickle=True)
    f_ref = np.sort(ref["self.mean_frequencies"].ravel())
    ts = TimeSeries(y, None, 256.0, output_names=["vib_l", "vib_r", "vib_t", "ref_x", "ref_y"])
    data, info = frfdata_from_time(ts)
    result = identify(data, Settings(n_bootstrap=20, jobs=1, band_hz=(0.5, 20.0)))
    phys = [m for m in result.physical_modes if m.frequency_hz < 15]
    found = found_within(f_ref, result.physical_modes)
    extra = [m.frequency_hz for m in phys if np.min(np.abs(f_ref / m.frequency_hz - 1)) >= 0.01]
    print(f"\nweimar: references {info['reference_names']}, nperseg {info['nperseg']}, "
          f"max lag {info['max_lag_s']} s, lag window decay {info['lag_window_decay_per_s']:.3f}/s")
    for m in phys:
        _, z = spectra.undo_exponential_window(m.frequency_hz, m.damping_ratio,
                                               info["lag_window_decay_per_s"])
        print(f"  {m.frequency_hz:8.4f} Hz  zeta {100 * m.damping_ratio:6.2f} % "
              f"(window removed {100 * float(z):6.2f} %)  physicalness {m.physicalness:.2f}")
    print(f"  reference modes found within 1 %: {int(found.sum())} of {f_ref.size}; "
          f"extra physical modes below 15 Hz: {np.round(extra, 3).tolist()}")
    assert info["references"] and len(phys) > 0


@pytest.mark.realdata
@pytest.mark.skipif(not REALDATA.is_dir(), reason="../shared/realdata is absent")
def test_realdata_ladisk_impacts():
    """Five hammer hits (records), H1; band 500-5000 Hz to keep it quick. Not yet strict."""
    hits = [np.load(REALDATA / "ladisk_impact_timeseries" / f"measurements_{k}.npy")
            for k in range(1, 6)]
    fs = 1.0 / (hits[0][0][1] - hits[0][0][0])
    ts = TimeSeries(np.concatenate([h[2] for h in hits]), np.concatenate([h[1] for h in hits]),
                    fs, output_names=["response"], input_names=["hammer"],
                    attributes={"quantity": "acceleration"})
    data, info = frfdata_from_time(ts)
    assert info["excitation"] == "impact" and data.records.shape[0] == 5
    inband = (data.frequency > 50) & (data.frequency < 10000)
    coherence = float(np.median(data.coherence[inband]))
    result = identify(data, Settings(n_bootstrap=20, jobs=1, band_hz=(500.0, 5000.0)))
    print(f"\nladisk: hits at {info['hits']}, record {info['nperseg']} samples, window "
          f"{info['window']}, median coherence 50 Hz-10 kHz {coherence:.4f}")
    for m in result.physical_modes:
        print(f"  {m.frequency_hz:9.2f} Hz  zeta {100 * m.damping_ratio:6.3f} %  "
              f"physicalness {m.physicalness:.2f}")
    assert coherence > 0.99 and len(result.physical_modes) > 0


def test_operational_records_stay_within_memory():
    from automodal.core.from_time import RECORDS_BYTES, operational_records

    assert operational_records(413444, 2029, 3, 2) == 48  # the plan's 48 stretches
    assert operational_records(20 * 600, 600, 5, 2) == 20  # stretches of max-lag samples
    assert operational_records(1000, 600, 5, 2) == 0  # one stretch says nothing
    big = operational_records(10**8, 16384, 64, 3)
    assert 2 <= big < 48 and big * 8193 * 64 * 3 * 16 <= RECORDS_BYTES
