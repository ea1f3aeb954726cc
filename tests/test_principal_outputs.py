"""The bootstrap replicates on the outputs' principal directions
(:func:`automodal.core.whitening.principal_outputs`): many sensors, few modes."""

from __future__ import annotations

import numpy as np
import pytest

from automodal.core import bilinear, bootstrap, noise, replicates, subspace, whitening
from automodal.core import simulate as sim
from automodal.core.modal import mac


@pytest.fixture(scope="module")
def many_sensors():
    """A 6 x 5 grid seen at all 30 masses, one input, the band holding its 4 lowest modes,
    1 % noise: scaled and whitened FRF, its variance, lines and the exact modes."""
    system = sim.damp(sim.grid(6, 5), "rayleigh", zeta=0.01)
    fn = np.sort(sim.natural_frequencies_hz(system))
    freq = sim.frequency_lines(0.5 * (fn[3] + fn[4]), 800)
    data, modes = sim.simulate_test(system, list(range(30)), [7], freq, "displacement",
                                    noise=0.01, seed=1)
    keep = data.frequency > 0
    w = 2 * np.pi * data.frequency[keep]
    T = bilinear.default_scale(w[0], w[-1])
    H = data.frf[keep]
    var = noise.estimate_noise(H).variance
    scale = np.sqrt(np.mean(var, axis=(0, 2)))
    return (H / scale[None, :, None], var / scale[None, :, None] ** 2,
            bilinear.to_unit_circle(w, T), T, modes, data)


def test_directions_are_real_orthonormal_and_fewer_than_the_outputs(many_sensors):
    Hs, var, *_ = many_sensors
    n = 16
    q = subspace.reference_block_rows(n, 30, whitening.output_rank(Hs, var))
    V = whitening.principal_outputs(Hs, var, n, q)
    assert V is not None and V.dtype == float
    r = V.shape[1]
    assert whitening.output_rank(Hs, var) <= r < 30
    assert (q - 1) * r >= 1.2 * n
    np.testing.assert_allclose(V.T @ V, np.eye(r), atol=1e-12)
    # twice the directions of the real-stacked whitened FRF above the noise edge
    level = np.mean(var, axis=(1, 2))
    X = (Hs / np.sqrt(level)[:, None, None]).transpose(1, 0, 2).reshape(30, -1)
    sv = np.linalg.svd(np.hstack([X.real, X.imag]), compute_uv=False)
    N, nu = Hs.shape[0], Hs.shape[2]
    above = int(np.sum(sv > (np.sqrt(2 * N * nu) + np.sqrt(30)) / np.sqrt(2)))
    assert r == 2 * above == 18
    # on 2 block rows the rank argument asks for more: (q - 1) r >= 1.2 n
    assert whitening.principal_outputs(Hs, var, n, 2).shape[1] == 20
    # the data's structure stays: the projection keeps all but the noise's share
    off = Hs - np.einsum("ek,nkj->nej", V, replicates.project_outputs(Hs, V))
    assert np.sum(np.abs(off) ** 2) < 1.5 * np.sum(var) * (30 - r) / 30


def test_no_projection_where_every_output_is_needed(many_sensors):
    Hs, var, *_ = many_sensors
    assert whitening.principal_outputs(Hs, var, 16, 1) is None  # one block row
    # few outputs: the kept directions would be all of them
    assert whitening.principal_outputs(Hs[:, :4], var[:, :4], 8, 5) is None
    # block rows too few for the order on fewer outputs than the data have
    assert whitening.principal_outputs(Hs, var, 60, 3) is None


def test_replicates_on_the_directions_find_the_modes_with_their_full_shapes(many_sensors):
    """As accurate as the replicates on all 30 outputs, on the block rows the pipeline
    gives (:func:`automodal.core.subspace.reference_block_rows` of the outputs' rank)."""
    Hs, var, z, T, modes, _ = many_sensors
    n = 16
    q = subspace.reference_block_rows(n, 30, whitening.output_rank(Hs, var))
    V = whitening.principal_outputs(Hs, var, n, q)
    basis = subspace.row_basis(z, q)
    weights = bootstrap.line_weights(Hs.shape[0], 8, np.random.default_rng(3))
    reduced = replicates.run_replicates(basis, Hs, n, T, weights, 1, output_basis=V)
    full = replicates.run_replicates(basis, Hs, n, T, weights, 1)
    true_f = np.asarray(modes.frequency_hz)
    band = np.argsort(true_f)[:4]  # the band holds the four lowest
    shapes_true = modes.shapes[:, band]
    for red, whole in zip(reduced, full):
        assert red.shapes.shape[0] == 30
        for k, f in enumerate(true_f[band]):
            got = []
            for rep in (red, whole):
                i = int(np.argmin(np.abs(np.abs(rep.poles) / (2 * np.pi) - f)))
                assert abs(np.abs(rep.poles[i]) / (2 * np.pi) / f - 1) < 1e-4
                got.append(np.asarray(mac(rep.shapes[:, [i]], shapes_true[:, [k]])).item())
            assert min(got) > 0.98 and abs(got[0] - got[1]) < 0.005


def test_noise_replicates_draw_on_every_output_then_project(many_sensors):
    """Each noise replicate is the reference FRF plus noise drawn on all the outputs,
    projected (the projected noise is correlated); the same as projecting by hand."""
    Hs, var, z, T, _, _ = many_sensors
    n = 16
    q = subspace.reference_block_rows(n, 30, whitening.output_rank(Hs, var))
    V = whitening.principal_outputs(Hs, var, n, q)
    basis = subspace.row_basis(z, q)
    seeds = np.array([11, 12, 13])
    lw = np.ones(Hs.shape[0])
    got = replicates.run_noise_replicates(basis, Hs, var, n, T, seeds, lw, 1, output_basis=V)
    std = np.sqrt(var / 2.0)

    def by_hand(b: int) -> np.ndarray:
        g = np.random.default_rng(int(seeds[b])).standard_normal((2,) + Hs.shape)
        return replicates.project_outputs(Hs + std * (g[0] + 1j * g[1]), V)

    want = replicates._own_schur_replicates(by_hand, 3, V.shape[1], basis, n, T, lw, 1, None,
                                            V)
    for a, b in zip(got, want):
        assert a.shapes.shape[0] == 30
        np.testing.assert_array_equal(a.poles, b.poles)
        np.testing.assert_array_equal(a.shapes, b.shapes)


def test_the_pipeline_projects_and_says_so(many_sensors):
    from automodal.pipeline import identify
    from automodal.settings import Settings

    *_, modes, data = many_sensors
    res = identify(data, Settings(seed=1, n_bootstrap=20))
    assert any("principal directions" in w for w in res.warnings)
    found = sorted(m.frequency_hz for m in res.modes if m.physical)
    true = np.sort(modes.frequency_hz)[:4]
    assert len(found) == 4
    np.testing.assert_allclose(found, true, rtol=1e-3)


def test_record_replicates_project_the_records(many_sensors):
    """Repeated records whose mean is the FRF: the replicates average resampled records,
    projected on the same directions (scaled first, then projected), and find the modes."""
    from dataclasses import replace

    from automodal.pipeline import identify
    from automodal.settings import Settings

    *_, modes, data = many_sensors
    system = sim.damp(sim.grid(6, 5), "rayleigh", zeta=0.01)
    clean, _ = sim.simulate_test(system, list(range(30)), [7], data.frequency,
                                 "displacement", noise=0.0, seed=1)
    rng = np.random.default_rng(5)
    R = 6
    H = clean.frf
    sig = 0.01 * np.sqrt(np.mean(np.abs(H) ** 2, axis=0, keepdims=True))
    noise_ = (rng.standard_normal((R, *H.shape))
              + 1j * rng.standard_normal((R, *H.shape))) / np.sqrt(2)
    records = H[None] + np.sqrt(R) * sig[None] * noise_
    with_records = replace(data, frf=records.mean(axis=0), records=records)
    res = identify(with_records, Settings(seed=1, n_bootstrap=20))
    assert any("repeated records" in w for w in res.warnings)
    assert any("principal directions" in w for w in res.warnings)
    found = sorted(m.frequency_hz for m in res.modes if m.physical)
    np.testing.assert_allclose(found, np.sort(modes.frequency_hz)[:4], rtol=1e-3)


def test_shape_spread_adds_the_left_out_directions(many_sensors, monkeypatch):
    """``mode_shape_std`` under the projection against a run on every output: without the
    left-out directions' share it was 0.50-0.77 of the full spread (rms over channels,
    median 0.65 over the four modes); with it, about the same."""
    from automodal.pipeline import identify
    from automodal.settings import Settings

    *_, data = many_sensors
    projected = identify(data, Settings(seed=1, n_bootstrap=100))
    assert any("principal directions" in w for w in projected.warnings)
    monkeypatch.setattr(whitening, "principal_outputs", lambda *args: None)
    full = identify(data, Settings(seed=1, n_bootstrap=100))
    ratios = []
    for a in (m for m in projected.modes if m.physical):
        b = min((m for m in full.modes if m.physical),
                key=lambda m: abs(m.frequency_hz - a.frequency_hz))
        sa, sb = np.asarray(a.mode_shape_std), np.asarray(b.mode_shape_std)
        ratios.append(np.sqrt(np.mean(sa**2) / np.mean(sb**2)))
    assert len(ratios) == 4
    assert 0.75 <= np.median(ratios) <= 1.3


def test_dropped_spread_of_isotropic_scatter():
    """Members scattered equally in every direction about a shape: the spread the kept
    half without structure shows, on each channel's share of the left-out directions."""
    from automodal.core.summary import dropped_spread

    rng = np.random.default_rng(0)
    ny, r = 40, 10
    basis = np.linalg.qr(rng.standard_normal((ny, ny)))[0]
    rep = basis[:, 0].astype(complex)
    members = rep[:, None] + 0.01 * (rng.standard_normal((ny, 4000))
                                     + 1j * rng.standard_normal((ny, 4000))) / np.sqrt(2)
    V = basis[:, :r]
    kept = V @ (V.T @ members)
    got = dropped_spread(kept, rep, V)
    left_out = 1.0 - np.sum(V**2, axis=1)
    np.testing.assert_allclose(got, 0.01 * np.sqrt(left_out), rtol=0.1)
    assert not dropped_spread(kept[:, :1], rep, V).any()


def test_a_split_run_says_its_split_and_its_directions_once(many_sensors, monkeypatch):
    """A band split into sub-bands, and parts split again: one warning for the split (with
    the number of sub-bands identified, as ``settings.orders.sub_bands`` lists them) and one
    for the principal directions (the range over the sub-bands), not one per part."""
    from automodal.core import sub_bands
    from automodal.pipeline import _leaf_orders, identify
    from automodal.settings import Settings

    *_, modes, data = many_sensors
    monkeypatch.setattr(sub_bands, "WORK_LIMIT", 1e4)  # every band with peaks too costly
    res = identify(data, Settings(seed=1, n_bootstrap=20))
    leaves = _leaf_orders(res.orders)
    assert len(leaves) >= 2
    split = [w for w in res.warnings if "sub-bands" in w and "identified in" in w]
    assert len(split) == 1 and f"identified in {len(leaves)} sub-bands" in split[0]
    directions = [w for w in res.warnings if "principal directions" in w]
    assert len(directions) == 1
    counts = sorted({o["replicate_directions"] for o in leaves} - {None})
    assert counts, leaves
    said = f"{counts[0]}" if len(counts) == 1 else f"{counts[0]}-{counts[-1]}"
    assert f"identified on {said} principal directions of the 30 outputs" in directions[0]


def test_the_directions_warning_says_how_many_sub_bands_used_them():
    from automodal.pipeline import _principal_warning

    one = _principal_warning([20], 25)
    assert "on 20 principal directions of the 25 outputs (twice those" in one
    assert "on 20 principal directions of the 25 outputs (in 1 of the 2 sub-bands, twice" \
        in _principal_warning([20], 25, 2)
    assert "on 12-18 principal directions of the 30 outputs (per sub-band, twice" \
        in _principal_warning([12, 18, 14], 30, 3)
