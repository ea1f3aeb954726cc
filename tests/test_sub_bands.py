"""Sub-bands: the plan (cuts at valleys, overlaps, counts) and a split run against a whole one."""

from __future__ import annotations

import cases
import numpy as np
import pytest

from automodal.core import simulate as sim
from automodal.core import sub_bands
from automodal.core.order import peak_lines
from automodal.pipeline import identify
from automodal.settings import Settings


def _siso_chain(n_dof: int = 12, noise: float = 0.0, seed: int = 0):
    system = sim.damp(sim.chain(n_dof), zeta=0.005)
    freq = sim.frequency_lines(1.1 * sim.natural_frequencies_hz(system).max(), 4000)
    data, modes = sim.simulate_test(system, [n_dof - 1], [n_dof - 1], freq, "displacement",
                                    noise=noise, seed=seed)
    return data, modes


def test_work_and_count():
    assert sub_bands.replicate_work(1000, 1, 1, 10) == 1000 * (11 * 2) ** 2
    assert sub_bands.sub_band_count(1e8, 2e8) == 1
    assert sub_bands.sub_band_count(8e8, 2e8) == 2  # 8e8 / 2^2 = 2e8
    assert sub_bands.sub_band_count(8.1e8, 2e8) == 3


def test_split_pays_only_where_the_sub_bands_models_are_smaller():
    # a dense grid whose order the modes set: 88 significant states, reference 176 on 8
    # block rows; halves of 44 -> 88 states on 4 block rows, a quarter of the work
    assert sub_bands.split_pays(1500, 37, 3, 88, 176, 8, 2.0, 2)
    # a SISO band of many modes, 256 states: its block rows follow the order
    assert sub_bands.split_pays(10_000, 1, 1, 86, 256, 257, 3.0, 3)
    # noise alone: n0 = 2, the reference at its floor (22) on 15 block rows from two
    # directions above the noise: four sub-bands would each need the same model
    assert not sub_bands.split_pays(6000, 35, 3, 2, 22, 15, 2.0, 4)
    # a reference near its floor falls too little to pay for nothing: n0 = 12 -> 32
    # states, halves of 6 -> 26 states on as many block rows (4 x 35 rows)
    assert not sub_bands.split_pays(6000, 35, 3, 12, 32, 4, 2.0, 2)
    assert not sub_bands.split_pays(6000, 35, 3, 88, 176, 8, 2.0, 1)


def test_plan_cuts_between_peaks_and_overlaps_by_one_resonance():
    data, _ = _siso_chain()
    f, H = data.frequency[1:], data.frf[1:]
    peaks = f[peak_lines(H)]
    plan = sub_bands.plan_sub_bands(f, H, 3)
    assert len(plan) == 3
    assert plan[0].core_hz[0] == f[0] and plan[-1].core_hz[1] == f[-1]
    for a, b in zip(plan[:-1], plan[1:]):
        assert a.core_hz[1] == b.core_hz[0]  # the cores tile the band
        cut = a.core_hz[1]
        assert not np.any(np.isclose(peaks, cut))  # no resonance is cut
        # each analysed band reaches over the cut by exactly one peak
        assert np.count_nonzero((peaks > cut) & (peaks <= a.analysed_hz[1])) == 1
        assert np.count_nonzero((peaks < cut) & (peaks >= b.analysed_hz[0])) == 1
    assert sum(b.n_peaks for b in plan) == peaks.size


def test_plan_keeps_one_band_when_too_few_peaks_or_lines():
    data, _ = _siso_chain(3)
    f, H = data.frequency[1:], data.frf[1:]
    assert len(sub_bands.plan_sub_bands(f, H, 1)) == 1
    assert len(sub_bands.plan_sub_bands(f, H, 10)) <= 3  # no more sub-bands than peaks
    few = slice(0, 40)  # 40 lines cannot hold a first scan stage of 60 states
    assert len(sub_bands.plan_sub_bands(f[few], H[few], 4)) == 1


def test_holds_splits_frequencies_once():
    plan = [sub_bands.SubBand((1.0, 5.0), (1.0, 6.0), 2),
            sub_bands.SubBand((5.0, 9.0), (4.0, 9.0), 2)]
    f = np.array([1.0, 4.99, 5.0, 9.0])
    assert plan[0].holds(f, False).tolist() == [True, True, False, False]
    assert plan[1].holds(f, True).tolist() == [False, False, True, True]


@pytest.fixture()
def split_everything(monkeypatch):
    """Make every band with a few peaks count as too costly."""
    monkeypatch.setattr(sub_bands, "WORK_LIMIT", 1e4)


def test_noise_free_split_run_finds_every_pole(split_everything):
    data, modes = _siso_chain()
    result = identify(data, Settings(seed=0, n_bootstrap=20))
    assert "sub_bands" in result.orders and len(result.orders["sub_bands"]) >= 2
    phys = sorted(m.frequency_hz for m in result.physical_modes)
    assert len(phys) == modes.frequency_hz.size  # no mode lost or doubled at a cut
    np.testing.assert_allclose(phys, np.sort(modes.frequency_hz), rtol=1e-5)
    zeta = [m.damping_ratio for m in sorted(result.physical_modes, key=lambda m: m.frequency_hz)]
    np.testing.assert_allclose(zeta, modes.damping_ratio[np.argsort(modes.frequency_hz)],
                               rtol=1e-3)
    # merged bookkeeping: distinct clusters, numbers 1..n, poles and fit over the band
    assert len({m.cluster for m in result.modes}) == len(result.modes)
    assert [m.mode_number for m in sorted(result.physical_modes, key=lambda m: m.frequency_hz)] \
        == list(range(1, len(phys) + 1))
    assert set(np.unique(result.poles.cluster)) <= {-1} | {m.cluster for m in result.modes}
    f_fit = result.frf_fit[0]
    assert np.all(np.diff(f_fit) > 0) and f_fit.size == result.n_lines
    assert result.frf_fit_error.shape == (1, 1)
    assert any("sub-bands" in w for w in result.warnings)


def test_split_run_on_noisy_chain_matches_the_whole_run(split_everything):
    case = cases.chain10_5pct()
    split = identify(case.data, Settings(seed=0))
    whole = identify(case.data, Settings(seed=0, sub_bands=False))
    assert "sub_bands" in split.orders and "sub_bands" not in whole.orders
    s_split, s_whole = cases.score(case, split.modes), cases.score(case, whole.modes)
    assert s_split["recall"] >= s_whole["recall"] - 0.1, (s_split, s_whole)
    assert s_split["median_rel_error"] < 1e-3


def test_explicit_order_and_setting_keep_one_model(split_everything):
    data, _ = _siso_chain(6)
    assert "sub_bands" not in identify(data, Settings(seed=0, n_bootstrap=10,
                                                      max_order=30)).orders
    assert "sub_bands" not in identify(data, Settings(seed=0, n_bootstrap=10,
                                                      sub_bands=False)).orders


def test_setting_is_validated():
    with pytest.raises(ValueError, match="sub_bands"):
        Settings(sub_bands="yes")


def test_plan_follows_the_modes_a_model_sees_where_peaks_undercount():
    data, modes = _siso_chain()
    f, H = data.frequency[1:], data.frf[1:]
    n_peaks = peak_lines(H).size
    # more modes than peaks (as where modes overlap): they set the groups
    seen = np.sort(np.concatenate([modes.frequency_hz, modes.frequency_hz[-4:] * 1.002]))
    plan = sub_bands.plan_sub_bands(f, H, 2, seen)
    assert len(plan) == 2
    assert sum(b.n_peaks for b in plan) == seen.size > n_peaks
    for a, b in zip(plan[:-1], plan[1:]):
        assert a.core_hz[1] == b.core_hz[0]
    # fewer modes than peaks: the peaks stay
    few = sub_bands.plan_sub_bands(f, H, 2, modes.frequency_hz[:3])
    assert sum(b.n_peaks for b in few) == n_peaks


def test_cuts_fall_at_the_deepest_valley_near_the_even_split():
    f = np.arange(200.0)
    logm = np.zeros(200)
    markers = np.array([10, 30, 50, 70, 90, 110, 130, 150, 170, 190])
    logm[markers] = 1.0
    logm[115:125] = -1.0  # the valley between markers 5 and 6 is the deepest
    logm[120] = -3.0
    logm[40] = -5.0  # deeper, but beyond a quarter of a group from the even split
    bands = sub_bands._split(f, logm, markers, 2)
    assert bands[0].core_hz[1] == 120.0  # the even split would cut between markers 4 and 5
    assert [b.n_peaks for b in bands] == [6, 4]


def test_stable_frequencies_are_the_poles_that_stay_put():
    from automodal.core.bilinear import poles_c2d
    from automodal.core.stabilization import stable_frequencies

    T = 0.01
    f = np.array([2.0, 5.0, 9.0])
    lam = -0.01 * 2 * np.pi * f + 2j * np.pi * f
    s = np.concatenate([lam, lam.conj()])
    noise = np.array([-1.0 + 2j * np.pi * 7.0, -1.0 - 2j * np.pi * 7.0])  # 2.3 % damped
    moved = np.array([-0.3 + 2j * np.pi * 7.5, -0.3 - 2j * np.pi * 7.5])
    m1 = (6, poles_c2d(np.concatenate([s, noise]), T), np.ones((2, 8), complex))
    m2 = (8, poles_c2d(np.concatenate([s, moved]), T), np.ones((2, 8), complex))
    got = stable_frequencies([m1, m2], T, (0.5, 20.0), 0.2)
    # natural frequencies of the three modes; the wandering pole is left out
    np.testing.assert_allclose(got, np.abs(lam) / (2 * np.pi), rtol=1e-9)
    assert stable_frequencies([m2], T, (0.5, 20.0), 0.2).size == 0


def test_sub_bands_keep_the_form_chosen_on_the_whole_band(split_everything):
    """A sub-band cut beside a peak has a trend that says little: the band's form is
    chosen once, and every sub-band is identified in it."""
    from automodal.core import simulate as sim

    system = sim.damp(sim.chain(6), zeta=0.01)
    freq = sim.frequency_lines(1.25 * sim.natural_frequencies_hz(system).max(), 1500)
    data, modes = sim.simulate_test(system, [5], [5], freq, "acceleration", noise=0.01, seed=0)
    result = identify(data, Settings(seed=0, n_bootstrap=10))
    bands = result.orders["sub_bands"]
    assert len(bands) >= 2
    assert result.orders["form"] == "receptance"  # a rise from 0.03 Hz to 6 modes
    assert [b["form"] for b in bands] == ["receptance"] * len(bands)
    found = np.array([m.frequency_hz for m in result.physical_modes])
    assert all(np.min(np.abs(found - f) / f) < 1e-3 for f in modes.frequency_hz)


def test_plan_counts_no_peak_where_noise_dominates():
    """With the noise variance, the plan's resonances are the modes, not the wiggles of
    noise (a seed-397 file's first sub-band held 39 noise peaks and none of the 38 modes):
    here a stretch below the first mode buried in noise and a faint floor elsewhere."""
    data, modes = _siso_chain()
    f, H = data.frequency[1:], data.frf[1:]
    quiet = f < 0.8 * modes.frequency_hz.min()
    rng = np.random.default_rng(3)
    sigma = np.full(H.shape, 1e-4 * np.abs(H).max())
    sigma[quiet] = 3.0 * np.abs(H[quiet]).mean()
    H = H + sigma * (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)) / 2**0.5
    blind = sub_bands.plan_sub_bands(f, H, 3)
    assert sum(b.n_peaks for b in blind) > 2 * modes.frequency_hz.size
    plan = sub_bands.plan_sub_bands(f, H, 3, variance=sigma**2)
    assert len(plan) == 3
    for i, b in enumerate(plan):
        assert b.n_peaks == np.count_nonzero(b.holds(modes.frequency_hz, i == len(plan) - 1))
    assert sum(b.n_peaks for b in plan) == modes.frequency_hz.size


def test_a_noise_weighted_split_run_plans_against_the_noise(split_everything, monkeypatch):
    """The pipeline gives the plan the noise variance of the FRF it plans on: the
    noise-weighted scan's, or where the scan fell back on the envelope weighting, the same
    noise in the enveloped channels' scaling (the relative noise of each entry unchanged)."""
    from automodal import pipeline

    case = cases.chain10_5pct()
    seen = []
    plan = sub_bands.plan_sub_bands

    def spy(f, H, n, modes_hz=None, variance=None):
        seen.append((H, variance))
        return plan(f, H, n, modes_hz, variance)

    monkeypatch.setattr(sub_bands, "plan_sub_bands", spy)
    identify(case.data, Settings(seed=0, n_bootstrap=10))
    assert seen and all(v is not None and v.shape == H.shape for H, v in seen)
    p = pipeline.prepare(case.data, Settings(), [])
    e = p.enveloped()
    assert not np.allclose(e.scales, p.scales)
    v = pipeline._noise_of_scaled(p, e)
    np.testing.assert_allclose(v / np.abs(e.Hs) ** 2, p.variance / np.abs(p.Hs) ** 2,
                               rtol=1e-10)
    np.testing.assert_allclose(pipeline._noise_of_scaled(p, p), p.variance, rtol=1e-12)
    assert pipeline._noise_of_scaled(e, e) is None


def _h1_of_noise_alone(n_lines: int, ny: int, nu: int, n_rec: int, seed: int):
    """H1 and multiple coherence of responses that are noise alone, ``n_rec`` records of
    random force."""
    from automodal.frfdata import FRFData

    rng = np.random.default_rng(seed)

    def cn(*shape):
        return (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) / np.sqrt(2)

    U, Y = cn(n_rec, n_lines, nu), cn(n_rec, n_lines, ny)
    Syu = np.einsum("rfi,rfj->fij", Y, U.conj()) / n_rec
    Suu = np.einsum("rfi,rfj->fij", U, U.conj()) / n_rec
    Syy = np.einsum("rfi,rfi->fi", Y, Y.conj()).real / n_rec
    H1 = np.linalg.solve(Suu.transpose(0, 2, 1), Syu.transpose(0, 2, 1)).transpose(0, 2, 1)
    coh = np.real(np.einsum("fij,fjk,fik->fi", H1, Suu, H1.conj())) / Syy
    return FRFData(frequency=np.linspace(0.01, 30.0, n_lines), frf=H1,
                   coherence=np.clip(coh, 0, 1)[:, :, None] * np.ones((1, 1, nu)),
                   quantity="acceleration")


def test_noise_alone_is_not_split():
    """H1 of noise alone on 35 outputs: n0 = 2 and a reference of 22 states on the block
    rows of two directions, too costly as one model by the work limit, and no smaller in
    sub-bands: it stays whole (it was cut in four, each the same model), and nothing in it
    is physical."""
    data = _h1_of_noise_alone(1000, 35, 3, 8, seed=2)
    res = identify(data, Settings(seed=1, n_bootstrap=20))
    orders = res.orders
    assert not orders.get("sub_bands") and orders["n0_rule"] != "sub-bands"
    assert orders["reference"] <= 24
    assert not any(m.physical for m in res.modes)


def test_a_scan_cut_short_for_a_split_that_does_not_pay_is_run_again(monkeypatch):
    """The scan stops early at a stage whose reference would be split; when the split is
    then refused (:func:`sub_bands.split_pays`), the band is scanned again to the end, as
    when the plan finds no cut."""
    import automodal.pipeline as pipeline

    monkeypatch.setattr(sub_bands, "WORK_LIMIT", 1e6)
    calls = []
    choose = pipeline._choose_orders

    def counted(*args, **kwargs):
        p, choice = choose(*args, **kwargs)
        calls.append((args[3], choice.complete))
        return p, choice

    monkeypatch.setattr(pipeline, "_choose_orders", counted)
    identify(_h1_of_noise_alone(1000, 35, 3, 8, seed=2), Settings(seed=1, n_bootstrap=10))
    assert calls[0][0] is not None and not calls[0][1]  # cut short, for a split
    assert len(calls) == 2 and calls[1][0] is None  # scanned again without the split


def test_a_sub_band_is_capped_only_by_a_scan_that_ran_to_its_end(split_everything, monkeypatch):
    """A sub-band's reference is at most its band's only where the band's scan ran to its
    end: a scan the split rule ended early stopped at a stage whose order had not settled,
    so its reference is no bound on a part of the band (a 100-output grid's top sub-band,
    78 of its 100 modes, was held at the 114 states of such a scan)."""
    import automodal.pipeline as pipeline

    calls = []
    choose = pipeline._choose_orders

    def recorded(*args, **kwargs):
        p, choice = choose(*args, **kwargs)
        calls.append((args[5], choice.reference, choice.complete))
        return p, choice

    monkeypatch.setattr(pipeline, "_choose_orders", recorded)
    data, _ = _siso_chain()
    result = identify(data, Settings(seed=0, n_bootstrap=10, jobs=1))
    assert "sub_bands" in result.orders
    top_cap, _, top_complete = calls[0]
    assert top_cap is None and not top_complete  # the whole band's scan, cut for the split
    assert len(calls) > 1 and calls[1][0] is None  # so its first sub-band is not capped
    settled = {reference for _, reference, complete in calls if complete}
    assert all(cap is None or cap in settled for cap, _, _ in calls)


def test_a_noise_model_too_low_does_not_send_the_order_up():
    """H1 of noise alone with a wrong ``n_averages`` attribute (40 for 8: the noise model
    5 times too low). The scan fits nothing to that noise and the envelope path takes
    over; its misfit floor kept falling to 108 states, split in four sub-bands on the
    block rows of the outputs' few directions: 122 s with 20 replicates. The floor's order
    is now kept to what those directions can hold (4 states each): 2 states, whole."""
    from dataclasses import replace

    data = _h1_of_noise_alone(1000, 35, 3, 8, seed=2)
    data = replace(data, attributes={**data.attributes, "n_averages": 40.0})
    res = identify(data, Settings(seed=1, n_bootstrap=20))
    assert res.orders["weighting"] == "envelope"
    assert res.orders["reference"] <= 24 and not res.orders.get("sub_bands")
    assert not any(m.physical for m in res.modes)
