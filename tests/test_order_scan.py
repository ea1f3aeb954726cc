"""Order selection with the misfit scan (core/order.py's scan and select_orders)."""

from __future__ import annotations

import numpy as np
import pytest

from automodal.core import bilinear, order, subspace
from automodal.core import simulate as sim
from automodal.errors import InputError


def _exact(n_dof: int = 3, outputs=(0, 1, 2), n_lines: int = 400):
    """Noise-free FRFs of a small chain, as the pipeline scales and weighs them."""
    system = sim.damp(sim.chain(n_dof), "rayleigh", zeta=0.02)
    freq = sim.frequency_lines(1.25 * sim.natural_frequencies_hz(system).max(), n_lines)
    data, _ = sim.simulate_test(system, list(outputs), [n_dof - 1], freq, "displacement",
                                noise=0.0)
    keep = data.frequency > 0
    w = 2 * np.pi * data.frequency[keep]
    T = bilinear.default_scale(w[0], w[-1])
    H = data.frf[keep]
    Hs = H / subspace.channel_scales(H)[None, :, None]
    return bilinear.to_unit_circle(w, T), Hs, subspace.envelope_weights(Hs)


def test_select_orders_finds_the_true_order_of_an_exact_system():
    z, Hs, lw = _exact()
    choice = order.select_orders(z, Hs, lw)
    assert choice.n0 == 6  # three modes, two states each
    assert choice.reference == order.excessive_order(6, choice.limit) == 26
    assert choice.scanned[0] == 2 and np.all(np.diff(choice.scanned) > 0)
    assert choice.misfit.shape == choice.scanned.shape
    assert choice.limit == order.order_limit(*Hs.shape)


def test_max_order_caps_the_scan_and_the_reference():
    z, Hs, lw = _exact()
    choice = order.select_orders(z, Hs, lw, max_order=9)
    assert choice.limit == 8
    assert choice.scanned[-1] <= 8 and choice.reference <= 8


def test_too_few_lines_are_refused_with_the_number_needed():
    z, Hs, lw = _exact(n_lines=400)
    n = 2000
    need = order.lines_needed(n, Hs.shape[1], Hs.shape[2])
    with pytest.raises(InputError, match=f"too few for model order {n}: .* at least {need}"):
        order.select_orders(z, Hs, lw, max_order=n, source="x.h5")
    with pytest.raises(InputError, match="too few: the identification needs at least"):
        order.select_orders(z[:3], Hs[:3], lw[:3])


def test_order_limit_and_lines_needed_agree():
    for ny, nu in ((1, 1), (3, 1), (4, 2)):
        for n in (4, 10, 40):
            need = order.lines_needed(n, ny, nu)
            assert order.order_limit(need, ny, nu) >= n
            assert order.order_limit(need - 1, ny, nu) < n


def test_count_peaks_counts_resonances():
    z, Hs, _ = _exact()
    assert order.count_peaks(Hs) == 3
    assert order.count_peaks(np.zeros((50, 2, 1))) == 0


def test_scan_orders_steps():
    o = order.scan_orders(200)
    assert list(o[:3]) == [2, 4, 6] and 60 in o and 62 not in o and 64 in o
    assert 124 not in o and 128 in o and o[-1] == 200
    assert np.all(o % 2 == 0)


def test_scan_stops_on_the_floor():
    z, Hs, lw = _exact()
    orders, misfit = order.scan(z, Hs, lw, 60, order.count_peaks(Hs))
    assert orders[-1] < 60  # stopped once the floor was reached
    assert order.order_at_floor(orders, misfit) == 6


def _noisy_siso(level: float = 0.1, seed: int = 0, n_lines: int = 3000):
    """A 4-DOF chain's accelerance at one point with additive noise of ``level`` times its
    RMS (a sensor noise floor: wiggles everywhere between the resonances), scaled as the
    pipeline scales it, with the noise's variance."""
    system = sim.damp(sim.chain(4), "rayleigh", zeta=0.01)
    freq = sim.frequency_lines(1.25 * sim.natural_frequencies_hz(system).max(), n_lines)
    data, _ = sim.simulate_test(system, [3], [3], freq, "acceleration")
    keep = data.frequency > 0
    H = data.frf[keep]
    rng = np.random.default_rng(seed)
    std = level * np.sqrt(np.mean(np.abs(H) ** 2))
    Hn = H + std / np.sqrt(2) * (rng.normal(size=H.shape) + 1j * rng.normal(size=H.shape))
    w = 2 * np.pi * data.frequency[keep]
    T = bilinear.default_scale(w[0], w[-1])
    return bilinear.to_unit_circle(w, T), Hn, np.ones(w.size), np.full(H.shape, std**2)


def test_peaks_of_a_noise_floor_do_not_count_with_the_noise_model():
    z, H, _, var = _noisy_siso()
    assert order.count_peaks(H) > 20  # the roughness rule alone counts the wiggles
    assert 1 <= order.count_peaks(H, variance=var) <= 6  # 4 modes
    zx, Hx, _ = _exact()  # noise-free: the same peaks with a negligible noise model
    assert order.count_peaks(Hx, variance=np.full(Hx.shape, 1e-30)) == 3


def test_scan_within_the_noise_stops_soon_after_the_true_order():
    z, H, lw, var = _noisy_siso()
    choice = order.select_orders(z, H, lw, variance=var)
    assert choice.rule == "significance" and choice.n0 <= 10
    assert choice.scanned[-1] <= 60  # not on to the largest order fitting noise


def test_fits_noise():
    # 400 lines, 1 x 1: 800 degrees of freedom less 4 a mode
    assert order.fits_noise(800.0, 400, 1, 1, 2)
    assert order.fits_noise(2.0 * 796, 400, 1, 1, 2)
    assert not order.fits_noise(2.0 * 796 + 1, 400, 1, 1, 2)
    assert not order.fits_noise(np.nan, 400, 1, 1, 2)


def test_reference_block_rows_follow_the_outputs_rank():
    assert subspace.reference_block_rows(96, 40) == subspace.block_rows(96, 40) == 4
    assert subspace.reference_block_rows(96, 40, 40) == 4
    assert subspace.reference_block_rows(96, 40, 20) == 7  # ceil(1.2 * 96 / 20) + 1
    assert subspace.reference_block_rows(10, 1, 1) == 11


def test_block_rows_asked_for_are_a_floor_the_lines_cap():
    z, Hs, lw = _exact()
    N, ny, nu = Hs.shape
    auto = order.select_orders(z, Hs, lw)
    assert auto.block_rows == subspace.block_rows(auto.reference, ny)
    assert order.select_orders(z, Hs, lw, min_block_rows=2).block_rows == auto.block_rows
    raised = order.select_orders(z, Hs, lw, min_block_rows=auto.block_rows + 5)
    assert raised.block_rows == auto.block_rows + 5
    assert raised.n0 == auto.n0 and raised.reference == auto.reference
    budget = int(2.0 * order.BOOTSTRAP_LINE_FRACTION * N * nu) // (ny + nu)
    assert order.select_orders(z, Hs, lw, min_block_rows=10 * N).block_rows == budget


def test_order_off_the_noise_takes_the_floor_above_and_the_directions_below():
    """When the significant order's model does not fit the noise: the misfit floor when it
    lies above n0; below it, at most 4 states per output direction above the noise (when
    the outputs show fewer directions than sensors), never below the floor."""
    from automodal.core.order import STATES_PER_DIRECTION, order_off_the_noise

    assert order_off_the_noise(4, 32, 39, 20) == (32, "floor")
    assert order_off_the_noise(92, 12, 20, 7) == (STATES_PER_DIRECTION * 7, "significance")
    assert order_off_the_noise(92, 40, 20, 7) == (40, "significance")
    assert order_off_the_noise(92, 12, 20, 20) == (92, "significance")  # rank = sensors
    assert order_off_the_noise(92, 12, 20, None) == (92, "significance")
    assert order_off_the_noise(20, 12, 20, 7) == (20, "significance")  # already below


def test_a_scan_ended_by_the_split_rule_is_marked_incomplete():
    # complete: a scan without split_work would choose the same, so the pipeline need not
    # repeat it when the band is not split after all
    z, Hs, lw = _exact()
    assert order.select_orders(z, Hs, lw).complete
    ample = subspace.replicate_work(*Hs.shape, 1000)
    assert order.select_orders(z, Hs, lw, split_work=ample).complete
    # work so small that every order's reference exceeds it: the scan stops at its first
    # stage whatever its misfit does
    cut = order.select_orders(z, Hs, lw, split_work=1.0)
    assert not cut.complete
    whole = order.select_orders(z, Hs, lw)
    same = order.select_orders(z, Hs, lw, split_work=ample)
    assert same.n0 == whole.n0 and same.reference == whole.reference
    assert np.array_equal(same.scanned, whole.scanned)


def test_a_rescan_reuses_the_stages_it_shares_and_chooses_as_a_fresh_scan(monkeypatch):
    """A scan cut by the split rule and redone without it (the band not split after all)
    takes the stages it went through from the dict the two calls share: the same choice as
    a fresh scan, with no stage scanned twice."""
    z, Hs, lw = _exact(n_dof=12, outputs=(0, 5, 11), n_lines=600)
    calls = []
    real = order.misfit_scan

    def counted(*args, **kwargs):
        calls.append(int(args[2][-1]))  # the stage's largest order
        return real(*args, **kwargs)

    monkeypatch.setattr(order, "misfit_scan", counted)
    fresh = order.select_orders(z, Hs, lw)
    n_fresh = len(calls)
    calls.clear()
    stages: dict = {}
    cut = order.select_orders(z, Hs, lw, split_work=1.0, stages=stages)
    assert not cut.complete and len(calls) >= 1
    first = list(calls)
    again = order.select_orders(z, Hs, lw, stages=stages)
    assert sorted(calls) == sorted(set(calls))  # no stage twice
    assert len(calls) == n_fresh and calls[: len(first)] == first
    assert again.n0 == fresh.n0 and again.reference == fresh.reference
    assert np.array_equal(again.scanned, fresh.scanned)
    np.testing.assert_array_equal(again.misfit, fresh.misfit)
    assert [m[0] for m in again.models] == [m[0] for m in fresh.models]
