"""The output-only plan (``automodal/core/ambient_plan.py``), decimation
(:func:`automodal.core.spectra.decimate`) and the pipeline's two-pass input stage
(:func:`automodal.pipeline.input_stage`).

The rule's constants were calibrated on simulated ambient tests of seeds 1 and 2 (see the
module's notes); the truth test here uses seeds 51 and 52, which nothing was tuned on.
"""

from __future__ import annotations

import numpy as np
import pytest

from automodal import Settings, identify
from automodal.core import ambient_plan as ap
from automodal.core import simulate as sim
from automodal.core import simulate_time as st
from automodal.core import spectra
from automodal.core.from_time import USABLE_FRACTION, frfdata_from_time
from automodal.pipeline import input_stage
from automodal.timedata import TimeSeries


def test_decimation_factor_keeps_the_band():
    # Weimar setup 1: 256 Hz, highest mode 13.86 Hz -> band to 17.3 Hz: q = 5 (20 Hz kept)
    q = ap.decimation_factor(256.0, ap.BAND_MARGIN * 13.86, USABLE_FRACTION)
    assert q == 5
    assert USABLE_FRACTION * 256.0 / (2 * q) >= ap.BAND_MARGIN * 13.86
    assert USABLE_FRACTION * 256.0 / (2 * (q + 1)) < ap.BAND_MARGIN * 13.86
    assert ap.decimation_factor(256.0, 150.0, USABLE_FRACTION) == 1  # above the band: none
    assert ap.decimation_factor(1000.0, 1000 * USABLE_FRACTION / 22, USABLE_FRACTION) == 11
    # 13 has a prime factor above 7 and needs stages: stepped down to 12, one stage
    assert ap.decimation_factor(1000.0, 1000 * USABLE_FRACTION / 26, USABLE_FRACTION) == 12
    assert ap.decimation_stages(12) == [12] and ap.decimation_stages(1) == []
    assert ap.decimation_stages(40) == [10, 4] and ap.decimation_stages(98) == [7, 7, 2]
    with pytest.raises(ValueError):
        ap.decimation_stages(13)


def test_lag_length_is_the_shorter_of_the_decay_and_the_record_bounds():
    fs = 100.0
    # long record: 10 decay times of the slowest mode (sigma = 0.5 /s -> 20 s = 2000 samples)
    assert ap.lag_length(10**6, fs, 0.5) == 2000
    # short record: T / MIN_BLOCKS
    assert ap.lag_length(48_000, fs, 0.5) == 48_000 // ap.MIN_BLOCKS
    assert ap.lag_length(48_000, fs, None) == 48_000 // ap.MIN_BLOCKS
    # never under MIN_LAG lags, never half the record or more
    assert ap.lag_length(2000, fs, 50.0) == ap.MIN_LAG
    assert ap.lag_length(100, fs, None) == 50
    # nor more than the line budget (a lightly damped mode in a long record)
    assert ap.lag_length(10**7, fs, 0.01) == ap.MAX_LAG


def test_plan_from_modes():
    f = np.array([1.23, 4.0, 13.86, 26.7])
    z = np.array([0.004, 0.002, 0.002, -0.001])
    plan = ap.plan_operational(61440, 256.0, f[:3], z[:3], USABLE_FRACTION)
    assert plan.decimation == 5 and plan.top_hz == pytest.approx(1.25 * 13.86)
    sigma = 0.004 * 2 * np.pi * 1.23
    assert plan.slowest_decay_per_s == pytest.approx(sigma)
    assert plan.nperseg == ap.lag_length(61440 // 5, 256.0 / 5, sigma) == 256
    # a band asked for sets the top, and modes above it do not count; the negative damping
    # of a mode does not set the lags
    asked = ap.plan_operational(61440, 256.0, f, z, USABLE_FRACTION, band_top_hz=30.0)
    assert asked.decimation == ap.decimation_factor(256.0, 30.0, USABLE_FRACTION) == 3
    assert asked.to_dict()["decimation"] == 3
    # a short record is decimated less: 48 stretches of 64 lags remain
    short = ap.plan_operational(4 * 3072, 256.0, f[:3], z[:3], USABLE_FRACTION)
    assert short.decimation == 4 and short.nperseg == ap.MIN_LAG
    undamped = ap.plan_operational(61440, 256.0, f[3:], z[3:], USABLE_FRACTION)
    assert undamped.to_dict()["slowest_decay_per_s"] is None
    assert undamped.nperseg == ap.lag_length(61440 // undamped.decimation, 1.0, None)
    with pytest.raises(ValueError, match="no mode"):
        ap.plan_operational(61440, 256.0, np.array([]), np.array([]), USABLE_FRACTION)


def test_decimate_keeps_the_band_and_removes_what_would_alias():
    fs, q, n = 512.0, 4, 8192
    t = np.arange(n) / fs
    x = np.c_[np.sin(2 * np.pi * 40.0 * t), np.sin(2 * np.pi * 100.0 * t)]
    y = spectra.decimate(x, q)
    assert y.shape == (n // q, 2)
    mid = slice(500, -500)  # away from the ends of the zero-phase filter
    tq = np.arange(y.shape[0]) * q / fs
    ripple = 1.5e-2  # 0.1 dB
    assert np.max(np.abs(y[mid, 0] - np.sin(2 * np.pi * 40.0 * tq[mid]))) < ripple
    assert np.max(np.abs(y[mid, 1])) < 1e-2  # 100 Hz is above the new Nyquist (64 Hz)
    assert spectra.decimate(x, 1).shape == x.shape


def test_decimated_half_spectra_say_their_rate():
    rng = np.random.default_rng(0)
    ts = TimeSeries(outputs=rng.standard_normal((8192, 2)), inputs=None, sample_rate=400.0)
    data, info = frfdata_from_time(ts, decimation=4, nperseg=128)
    assert info["decimation"] == 4 and info["analysed_sample_rate_hz"] == 100.0
    assert data.frequency[-1] <= USABLE_FRACTION * 50.0 + 1e-9
    assert info["n_segments"] == 2048 // 128
    forced = TimeSeries(outputs=ts.outputs[:, :1], inputs=ts.outputs[:, 1:], sample_rate=400.0)
    with pytest.raises(ValueError, match="operational"):
        frfdata_from_time(forced, decimation=2)


def test_references_see_a_mode_on_the_first_reference_s_node():
    # 3 x 2 grid: two modes have a node at DOFs 2 and 5, which see the others best; a
    # single reference there lost them in every seed before the coverage condition
    system = sim.damp(sim.grid(3, 2), zeta=0.01)
    ts, modes, _ = st.simulate_time_test(system, None, None, "ambient", "acceleration",
                                         0.01, 3, duration=400.0)
    refs = spectra.choose_references(ts.outputs, ts.sample_rate)
    shapes = np.abs(modes.shapes)  # (n_out, n_modes)
    seen = shapes[refs].max(axis=0) / shapes.max(axis=0)
    assert len(refs) >= 2 and seen.min() > 0.2, (refs, seen)


@pytest.mark.parametrize("seed", [51, 52])
def test_truth_ambient_oversampled_is_decimated(seed):
    """An ambient test sampled 4 times faster than needed: the first pass finds the modes,
    the plan decimates back to the band and chooses the lags; every clear mode within 0.5 %
    in frequency and 20 % in damping (seeds not used for calibration)."""
    system = sim.damp(sim.chain(4), zeta=0.01)
    fs = 4 * st.default_sample_rate(system)
    ts, modes, plan = st.simulate_time_test(system, None, None, "ambient", "acceleration",
                                            0.01, seed, sample_rate=fs, duration=600.0)
    s = Settings(seed=seed, n_bootstrap=30, jobs=1)
    data = input_stage(ts, s)
    info = data.attributes["time_analysis"]
    assert info["decimation"] >= 3 and info["plan"]["decimation"] == info["decimation"]
    result = identify(data, s)
    phys = [m for m in result.modes if m.physical]
    clear = st.clear_modes(modes, fs / 4 / 2.56, "acceleration")
    k = st.nearest_modes(modes.frequency_hz[clear], [m.frequency_hz for m in phys])
    assert np.all(k >= 0), modes.frequency_hz[clear][k < 0]
    f = np.array([phys[i].frequency_hz for i in k])
    z = np.array([phys[i].damping_ratio for i in k])
    assert np.max(np.abs(f / modes.frequency_hz[clear] - 1)) < 5e-3
    assert np.max(np.abs(z / modes.damping_ratio[clear] - 1)) < 0.20, z


def test_input_stage_without_a_physical_mode_keeps_the_first_pass():
    rng = np.random.default_rng(4)
    ts = TimeSeries(outputs=rng.standard_normal((20000, 3)), inputs=None, sample_rate=100.0)
    data = input_stage(ts, Settings(seed=0, n_bootstrap=10, jobs=1))
    plan = data.attributes["time_analysis"]["plan"]
    assert plan["first_pass_modes_hz"] == [] and "no physical mode" in plan["note"]
    assert data.attributes["time_analysis"]["decimation"] == 1


def test_input_stage_passes_frfs_and_forced_records_through():
    rng = np.random.default_rng(5)
    u = rng.standard_normal((8192, 1))
    ts = TimeSeries(outputs=np.c_[u[:, 0] + 0.1 * rng.standard_normal(8192)], inputs=u,
                    sample_rate=100.0)
    data = input_stage(ts)
    assert data.attributes["analysis"] == "h1" and "plan" not in data.attributes["time_analysis"]
    assert input_stage(data) is data


def test_the_first_pass_keeps_the_automatic_block_rows(monkeypatch):
    """The first pass only finds the modes: ``block_rows`` asked for the analysis (its
    warnings would be lost there) does not slow it."""
    import automodal.pipeline as pipeline

    seen = []
    real = pipeline._identify

    def spy(data, s, *args, **kwargs):
        seen.append(s.block_rows)
        return real(data, s, *args, **kwargs)

    monkeypatch.setattr(pipeline, "_identify", spy)
    rng = np.random.default_rng(4)
    ts = TimeSeries(outputs=rng.standard_normal((20000, 3)), inputs=None, sample_rate=100.0)
    input_stage(ts, Settings(seed=0, n_bootstrap=10, jobs=1, block_rows=12))
    assert seen and seen[0] is None
