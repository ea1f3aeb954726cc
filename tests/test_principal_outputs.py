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
            bilinear.to_unit_circle(w, T), T, modes)


def test_directions_are_real_orthonormal_and_fewer_than_the_outputs(many_sensors):
    Hs, var, *_ = many_sensors
    n, q = 16, subspace.block_rows(16, 30)
    V = whitening.principal_outputs(Hs, var, n, q)
    assert V is not None and V.dtype == float
    r = V.shape[1]
    assert whitening.output_rank(Hs, var) <= r < 30
    assert (q - 1) * r >= 1.2 * n
    np.testing.assert_allclose(V.T @ V, np.eye(r), atol=1e-12)
    # the data's structure stays: the projection keeps all but the noise's share
    off = Hs - np.einsum("ek,nkj->nej", V, replicates.project_outputs(Hs, V))
    assert np.sum(np.abs(off) ** 2) < 1.5 * np.sum(var) * (30 - r) / 30


def test_no_projection_where_every_output_is_needed(many_sensors):
    Hs, var, *_ = many_sensors
    # few outputs: the kept directions would be all of them
    assert whitening.principal_outputs(Hs[:, :4], var[:, :4], 8, 5) is None
    # block rows too few for the order on fewer outputs than the data have
    assert whitening.principal_outputs(Hs, var, 60, 3) is None


def test_replicates_on_the_directions_find_the_modes_with_their_full_shapes(many_sensors):
    """As accurate as the replicates on all 30 outputs, on the block rows the pipeline
    gives (:func:`automodal.core.subspace.reference_block_rows` of the outputs' rank)."""
    Hs, var, z, T, modes = many_sensors
    n = 16
    q = subspace.reference_block_rows(n, 30, whitening.output_rank(Hs, var))
    V = whitening.principal_outputs(Hs, var, n, q)
    basis = subspace.row_basis(z, q)
    weights = bootstrap.line_weights(Hs.shape[0], 8, np.random.default_rng(3))
    reduced = replicates.run_replicates(basis, replicates.project_outputs(Hs, V), n, T,
                                        weights, 1, output_basis=V)
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
