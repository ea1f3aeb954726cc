"""Frequency-domain subspace identification on systems with known modes."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import subspace_angles

from automodal.core import bilinear, subspace
from automodal.core import simulate as sim
from automodal.core.modal import mac, modes_of_discrete, mpc


def _system(kind: str):
    if kind == "chain8":
        return sim.damp(sim.chain(8), "rayleigh", zeta=0.01)
    if kind == "chain8_nonprop":
        return sim.damp(sim.chain(8), "nonproportional", zeta=0.02)
    if kind == "grid":
        return sim.damp(sim.grid(3, 4), "nonproportional", zeta=0.01)
    raise ValueError(kind)


def _data(system, outputs, inputs, quantity, n_lines=800, noise=0.0, seed=0):
    f_max = 1.25 * sim.natural_frequencies_hz(system).max()
    freq = sim.frequency_lines(f_max, n_lines)
    data, modes = sim.simulate_test(system, outputs, inputs, freq, quantity, noise=noise, seed=seed)
    w = 2 * np.pi * data.frequency
    T = bilinear.default_scale(w[0], w[-1])
    return data, modes, bilinear.to_unit_circle(w, T), T


def _match(identified, exact):
    """Relative pole errors and MACs of the identified mode nearest each exact pole."""
    errs, macs = [], []
    for j, lam in enumerate(exact.poles):
        i = int(np.argmin(np.abs(identified.poles - lam)))
        errs.append(abs(identified.poles[i] - lam) / abs(lam))
        macs.append(mac(identified.shapes[:, i], exact.shapes[:, j])[0, 0])
    return np.array(errs), np.array(macs)


CASES = [
    # name, system, outputs, inputs, quantity
    ("siso", "chain8", [7], [7], "displacement"),
    ("simo", "chain8", [1, 4, 7], [7], "velocity"),
    ("mimo", "chain8", [0, 2, 4, 7], [0, 7], "acceleration"),
    ("nonprop_mimo", "chain8_nonprop", [0, 3, 5, 7], [2, 7], "displacement"),
    ("nonprop_siso_acc", "chain8_nonprop", [6], [6], "acceleration"),
    ("grid_mimo", "grid", [0, 2, 5, 7, 9, 11], [0, 11], "velocity"),
]


@pytest.mark.parametrize("method", ["qr", "gram", "auto"])
@pytest.mark.parametrize("name,kind,outputs,inputs,quantity", CASES, ids=[c[0] for c in CASES])
def test_noise_free_recovers_every_pole(method, name, kind, outputs, inputs, quantity):
    system = _system(kind)
    data, exact, z, T = _data(system, outputs, inputs, quantity)
    n = 2 * exact.n_modes
    if method == "gram" and len(outputs) == 1:
        pytest.skip("high-order SISO needs the QR path: the Gram path squares the data")
    model = subspace.identify(z, data.frf, n, T, method=method)
    ident = modes_of_discrete(model.Ad, model.Cd, T)
    assert len(ident) == exact.n_modes
    errs, macs = _match(ident, exact)
    assert errs.max() < 1e-6, errs
    if len(outputs) > 1:
        assert macs.min() > 0.9999, macs


def test_auto_falls_back_to_qr_when_gram_cannot_resolve():
    system = _system("chain8")
    data, exact, z, T = _data(system, [7], [7], "displacement")
    model = subspace.identify(z, data.frf, 16, T, method="auto")
    assert model.path == "qr"
    # a noisy MIMO problem stays on the fast path
    data, exact, z, T = _data(system, [0, 3, 7], [7], "displacement", noise=0.01)
    assert subspace.identify(z, data.frf, 16, T, method="auto").path == "gram"


@pytest.mark.parametrize(
    "outputs,inputs,n",
    [([7], [7], 16), ([1, 4, 7], [7], 30), ([0, 2, 4, 6, 7], [0, 7], 40)],
)
def test_qr_and_gram_paths_give_the_same_subspace_on_noisy_data(outputs, inputs, n):
    system = _system("chain8")
    data, _, z, T = _data(system, outputs, inputs, "displacement", noise=0.02, seed=3)
    H = data.frf / subspace.channel_scales(data.frf)[None, :, None]
    q = subspace.block_rows(n, len(outputs))
    for kind in ("monomial", "orthonormal"):
        basis = subspace.row_basis(z, q, kind)
        O_qr, _ = subspace.observability_from_l22(subspace.projected_output_qr(basis, H), n)
        O_gr, _ = subspace.observability_from_schur(
            subspace.schur_complement(subspace.gram_sums(basis, H)), n
        )
        if kind == "monomial" and len(outputs) == 1:
            continue  # ill-conditioned monomials at q = n + 1: compared in the other basis
        assert np.max(subspace_angles(O_qr, O_gr)) < 1e-8


@pytest.mark.parametrize("kind", ["monomial", "orthonormal", "orthonormal-own-sums",
                                  "orthonormal-narrow"])
@pytest.mark.parametrize("chunk_bytes", [64 * 2**20, 5_000])
def test_gram_sums_are_the_weighted_sums_they_define(kind, chunk_bytes):
    """Every block of the Gram sums equals its definition, summed line by line, whatever
    the chunks and the map (a thread pool gives the very same numbers): the monomial power
    sums, the orthonormal basis's sums formed in its product basis (on a wide arc and on a
    narrow one, where the monomials' Gram matrix has a condition of 1e16), and its own
    ``q^2`` products."""
    from concurrent.futures import ThreadPoolExecutor

    rng = np.random.default_rng(4)
    N, ny, nu, q, B = 57, 3, 2, 4, 5
    arc = (0.3, 0.31) if kind == "orthonormal-narrow" else (0.3, 2.0)
    z = np.exp(1j * np.linspace(*arc, N))
    H = rng.standard_normal((N, ny, nu)) + 1j * rng.standard_normal((N, ny, nu))
    w = rng.poisson(1.0, (B, N)).astype(float)
    basis = subspace.row_basis(z, q, kind.split("-")[0])
    expected = {"monomial": "toeplitz", "orthonormal-own-sums": "direct"}.get(kind, "product")
    if kind == "orthonormal-own-sums":
        basis = subspace.RowBasis(basis.values, basis.shift, basis.p0, False)
    assert basis.sums_kind == expected
    sums = subspace.gram_sums(basis, H, w, chunk_bytes=chunk_bytes)
    with ThreadPoolExecutor(2) as pool:
        threaded = subspace.gram_sums(basis, H, w, chunk_bytes=chunk_bytes, map_fn=pool.map)
    P = basis.values
    for b in range(B):
        a = np.einsum("k,ik,jk->ij", w[b], P, P.conj())  # sum c p_i conj(p_j)
        yu = np.einsum("k,ik,jk,kab->ijab", w[b], P, P.conj(), H)
        yy = np.einsum("k,ik,jk,kab,kcb->ijac", w[b], P, P.conj(), H, H.conj())
        tu, gyu, gyy = sums.blocks(b)
        scale = np.abs(yy).max()
        assert np.abs(tu - a.real).max() < 1e-12 * np.abs(a).max()
        assert np.abs(gyu - yu.real).max() < 1e-12 * np.abs(yu).max()
        assert np.abs(gyy - yy.real).max() < 1e-12 * scale
        for got, again in zip(sums.blocks(b), threaded.blocks(b)):
            assert np.array_equal(got, again)
    stacked = sums.blocks(slice(1, 4))  # a slice of replicates: each as if alone
    for got, b in zip(zip(*stacked), range(1, 4)):
        for x, y in zip(got, sums.blocks(b)):
            np.testing.assert_allclose(x, y, rtol=0, atol=1e-13 * np.abs(y).max())


def test_product_basis_represents_the_products_and_refuses_points_off_the_circle():
    """``p_i conj(p_j)`` is a combination of 2q - 1 orthonormal real functions on the unit
    circle, to 1e-13 on a wide arc and within the tolerance (1e-10) on an arc of 0.002 rad
    (monomial Gram condition 1e17); off the circle (about the origin) the products leave
    that span and no product basis is given."""
    for arc, N, q, tol in [((0.1, 3.0), 800, 7, 1e-13), ((0.1, 0.102), 3000, 10, 1e-10),
                           ((0.1, 0.102), 6000, 14, 1e-10)]:
        z = np.exp(1j * np.linspace(*arc, N))
        basis = subspace.orthonormal_basis(z, q)
        assert basis.sums_kind == "product"
        pb = basis.products
        G, M = pb.functions, pb.coefficients
        assert G.shape == (2 * q - 1, N) and np.isrealobj(G)
        np.testing.assert_allclose(G @ G.T, np.eye(2 * q - 1), atol=1e-12)
        A = basis.values[:, None, :] * basis.values[None, :, :].conj()
        R = np.einsum("ijc,ck->ijk", M, G) - A
        assert np.max(np.linalg.norm(R, axis=2) / np.linalg.norm(A, axis=2)) < tol
    z = 0.2 + np.exp(1j * np.linspace(0.1, 3.0, 200))
    assert subspace.orthonormal_basis(z, 5).sums_kind == "direct"


def test_weighted_gram_equals_qr_on_repeated_lines():
    """A bootstrap weight c_k is the same as c_k copies of line k, on both paths."""
    system = _system("chain8")
    data, _, z, T = _data(system, [0, 3, 7], [7], "displacement", noise=0.01, n_lines=300)
    H = data.frf
    rng = np.random.default_rng(0)
    w = rng.multinomial(z.size, np.full(z.size, 1 / z.size), size=3).astype(float)
    q, n = subspace.block_rows(16, 3), 16
    basis = subspace.row_basis(z, q, "monomial")
    sums = subspace.gram_sums(basis, H, w, chunk_bytes=20_000)  # several chunks
    for b in range(3):
        O_gr, _ = subspace.observability_from_schur(subspace.schur_complement(sums, b), n)
        # explicit copies of lines on the QR path
        idx = np.repeat(np.arange(z.size), w[b].astype(int))
        rep = subspace.RowBasis(basis.values[:, idx], basis.shift, basis.p0, basis.monomial)
        O_qr, _ = subspace.observability_from_l22(subspace.projected_output_qr(rep, H[idx]), n)
        assert np.max(subspace_angles(O_qr, O_gr)) < 1e-8
        O_w, _ = subspace.observability_from_l22(subspace.projected_output_qr(basis, H, w[b]), n)
        assert np.max(subspace_angles(O_qr, O_w)) < 1e-8


@pytest.mark.parametrize("quantity", ["displacement", "velocity", "acceleration"])
def test_bd_and_synthesis_reproduce_the_frf(quantity):
    system = _system("chain8_nonprop")
    data, exact, z, T = _data(system, [0, 3, 7], [2, 7], quantity)
    model = subspace.identify(z, data.frf, 16, T)
    w = 2 * np.pi * data.frequency
    H_model = model.frf(w)
    rel = np.linalg.norm(H_model - data.frf) / np.linalg.norm(data.frf)
    assert rel < 1e-8
    # and the continuous-time model gives the same FRF
    A, B, C, D = model.continuous()
    H_ct = subspace.frequency_response(A, B, C, D, 1j * w)
    assert np.linalg.norm(H_ct - data.frf) / np.linalg.norm(data.frf) < 1e-8


def test_bilinear_round_trip():
    rng = np.random.default_rng(1)
    system = _system("chain8_nonprop")
    A, B, C, D = sim.state_space(system, [1, 5], [1], "acceleration")  # D != 0
    T = 0.013
    back = bilinear.d2c(*bilinear.c2d(A, B, C, D, T), T)
    for x, y in zip((A, B, C, D), back):
        assert np.allclose(x, y, rtol=1e-9, atol=1e-9 * max(1.0, np.abs(x).max()))
    s = rng.normal(size=5) + 1j * rng.normal(size=5)
    assert np.allclose(bilinear.poles_d2c(bilinear.poles_c2d(s, T), T), s)
    w = np.linspace(0, 1000, 7)
    z = bilinear.to_unit_circle(w, T)
    assert np.allclose(np.abs(z), 1)
    assert np.allclose(bilinear.poles_d2c(z[1:], T), 1j * w[1:])


def test_channel_scaling_does_not_change_the_modes():
    system = _system("chain8")
    data, exact, z, T = _data(system, [0, 3, 7], [7], "displacement")
    H = data.frf * np.array([1e-6, 1.0, 1e4])[None, :, None]
    model = subspace.identify(z, H, 16, T)
    ident = modes_of_discrete(model.Ad, model.Cd, T)
    errs, _ = _match(ident, exact)
    assert errs.max() < 1e-6
    shapes = exact.shapes * np.array([1e-6, 1.0, 1e4])[:, None]
    for j, lam in enumerate(exact.poles):
        i = int(np.argmin(np.abs(ident.poles - lam)))
        assert mac(ident.shapes[:, i], shapes[:, j])[0, 0] > 0.9999


def test_too_few_lines_is_refused():
    system = _system("chain8")
    data, _, z, T = _data(system, [7], [7], "displacement", n_lines=20)
    with pytest.raises(ValueError, match="need"):
        subspace.identify(z, data.frf, 40, T)
    assert subspace.min_lines(40, 1, 1) == 41


def test_mpc_of_real_and_complex_shapes():
    assert mpc(np.array([1.0, -2.0, 0.5]))[0] == pytest.approx(1.0)
    assert mpc(np.array([1.0, 1j]))[0] == pytest.approx(0.0)
    # rotation invariant
    v = np.array([1.0, 0.3 + 0.2j, -0.5])
    assert mpc(v)[0] == pytest.approx(mpc(v * np.exp(0.7j))[0])


def test_bd_normal_equations_match_the_stacked_problem():
    system = _system("chain8_nonprop")
    data, _, z, T = _data(system, [0, 3, 7], [2, 7], "velocity", noise=0.01, seed=4)
    model = subspace.identify(z, data.frf, 20, T, estimate_bd_=False)
    w = np.random.default_rng(2).uniform(0.5, 2.0, z.size)
    B1, D1 = subspace.estimate_bd(z, data.frf, model.Ad, model.Cd, weights=w)
    B2, D2 = subspace._estimate_bd_stacked(z, data.frf, model.Ad, model.Cd, True, w)
    H1 = subspace.frequency_response(model.Ad, B1, model.Cd, D1, z)
    H2 = subspace.frequency_response(model.Ad, B2, model.Cd, D2, z)
    assert np.linalg.norm(H1 - H2) / np.linalg.norm(H2) < 1e-6


def _orthonormal(rng, m, n):
    return np.linalg.qr(rng.standard_normal((m, n)))[0]


@pytest.mark.parametrize("kind", ["monomial", "orthonormal"])
def test_normal_equation_shift_invariance_equals_least_squares(kind):
    """The Woodbury form of the shift invariance is the least-squares solution, stacked
    or alone, and a nearly rank-deficient O_up goes to lstsq."""
    rng = np.random.default_rng(3)
    ny, q, n = 3, 6, 12
    z = np.exp(1j * np.linspace(0.1, 2.5, 200))
    basis = subspace.row_basis(z, q, kind)
    O = np.stack([_orthonormal(rng, q * ny, n) for _ in range(4)])
    # replicate 3: one state lives in the last block row only (sigma_min(O_up) = 0)
    O[3, :, 0] = 0.0
    O[3, -ny:, 0] = np.array([1.0, 0.0, 0.0])
    O[3] = np.linalg.qr(O[3])[0] * np.sign(np.diag(np.linalg.qr(O[3])[1]))
    A, C = subspace.shift_invariance(O, ny, basis)
    for b in range(4):
        up = O[b, :-ny]
        if basis.monomial:
            rhs = O[b, ny:]
        else:
            rhs = np.einsum("ij,iak->jak", basis.shift, O[b].reshape(q, ny, n)).reshape(-1, n)
        ref = np.linalg.lstsq(up, rhs, rcond=None)[0]
        assert np.max(np.abs(A[b] - ref)) < 1e-10 * max(1.0, np.max(np.abs(ref)))
        A1, C1 = subspace.shift_invariance(O[b], ny, basis)
        np.testing.assert_array_equal(A1, A[b])
        np.testing.assert_array_equal(C1, C[b])
        np.testing.assert_array_equal(C[b], O[b, :ny] / basis.p0)


def test_stacked_replicates_equal_replicates_alone():
    """A replicate's modes do not depend on the stack it is computed in (so not on
    ``jobs``), and the stacked Schur complements equal the one-by-one ones."""
    from automodal.core import bootstrap

    system = _system("chain8")
    data, _, z, T = _data(system, [0, 3, 7], [7], "displacement", noise=0.01, n_lines=300)
    rng = np.random.default_rng(1)
    w = bootstrap.line_weights(z.size, 5, rng).astype(float)
    n = 24
    basis = subspace.row_basis(z, subspace.block_rows(n, 3))
    sums = subspace.gram_sums(basis, data.frf, w)
    S = subspace.schur_complement(sums, slice(0, 5))
    for b in range(5):
        np.testing.assert_allclose(S[b], subspace.schur_complement(sums, b), rtol=0,
                                   atol=1e-12 * np.abs(S[b]).max())
    stacked = bootstrap.replicates_from_schur(S, n, basis, T, 3)
    for b in range(5):
        alone = bootstrap.replicates_from_schur(S[b : b + 1], n, basis, T, 3)[0]
        np.testing.assert_array_equal(alone.poles, stacked[b].poles)
        np.testing.assert_array_equal(alone.shapes, stacked[b].shapes)
        # and the same modes as the reference route (eig of one model, modes_of_discrete)
        O, _ = subspace.observability_from_schur(S[b], n)
        A, _ = subspace.shift_invariance(O, 3, basis)
        C = subspace.output_matrix(O, *np.linalg.eig(A), basis, 3)[1]
        ref = modes_of_discrete(A, C, T)
        np.testing.assert_allclose(stacked[b].poles, ref.poles, rtol=1e-12)
        assert np.all(np.abs(np.sum(stacked[b].shapes.conj() * ref.shapes, axis=0)) > 1 - 1e-10)


def test_qr_observability_of_fewer_columns_than_the_order_is_completed():
    """An ``L22`` of 9 columns at order 10 (a replicate of few lines) gives 10 orthonormal
    directions, its own 9 first, like the Gram path."""
    rng = np.random.default_rng(0)
    l22 = rng.standard_normal((11, 9))
    O, sv = subspace.observability_from_l22(l22, 10)
    assert O.shape == (11, 10) and sv.shape == (10,)
    np.testing.assert_allclose(O.T @ O, np.eye(10), atol=1e-12)
    np.testing.assert_allclose(sv[:9], np.linalg.svd(l22, compute_uv=False))
    assert sv[9] == 0.0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_default_row_basis_keeps_the_modes_of_noisy_data(seed):
    """With noise the row basis weighs the SVD's rows: the default (orthonormal over the
    lines) keeps them as white as the noise over the lines. A 9-DOF chain seen by 5 of its
    masses, 1 % additive noise, noise-weighted, over-sized to 36 states: 8-9 of the 9 modes
    within 0.5 % on seeds 0-5, where monomial rows gave 4."""
    from automodal.core import noise as noise_model
    from automodal.core import whitening

    system = sim.damp(sim.chain(9), "rayleigh", zeta=0.008)
    freq = sim.frequency_lines(1.1 * sim.natural_frequencies_hz(system).max(), 3000)
    outputs = [0, 1, 3, 4, 5]
    data, modes = sim.simulate_test(system, outputs, [8], freq, "displacement", noise=0.01,
                                    seed=seed, noise_kind="additive")
    w = 2 * np.pi * data.frequency
    T = bilinear.default_scale(w[0], w[-1])
    z = bilinear.to_unit_circle(w, T)
    weights, scales = whitening.whitening(noise_model.estimate_noise(data.frf).variance)
    Hs = data.frf / scales[None, :, None]
    model = subspace.identify(z, Hs, 36, T, q=subspace.block_rows(36, len(outputs)),
                              weights=weights, scale=False)
    lam = bilinear.poles_d2c(np.linalg.eigvals(model.Ad), T)
    lam = lam[lam.imag > 0]
    found = [np.min(np.abs(lam - p)) / abs(p) < 5e-3 for p in modes.poles]
    assert sum(found) >= 8, found


def test_real_stacked_gram_is_that_of_the_data_matrices_to_the_bit():
    rng = np.random.default_rng(8)
    for q, N, ny, nu in [(7, 300, 3, 2), (5, 200, 1, 1), (4, 150, 6, 3)]:
        P = rng.standard_normal((q, N)) + 1j * rng.standard_normal((q, N))
        H = rng.standard_normal((N, ny, nu)) + 1j * rng.standard_normal((N, ny, nu))
        Z = np.vstack(subspace.data_matrices(P, H))
        W = np.concatenate([Z.real, Z.imag], axis=1)
        np.testing.assert_array_equal(subspace._real_stacked_gram(P, H), W @ W.T)


def test_schur_from_data_is_the_same_on_any_number_of_workers():
    """Its chunks of lines are fixed by the size alone and added in order."""
    rng = np.random.default_rng(5)
    N, ny, nu, q = 2500, 4, 2, 6
    z = np.exp(1j * np.linspace(0.2, 2.8, N))
    H = rng.standard_normal((N, ny, nu)) + 1j * rng.standard_normal((N, ny, nu))
    basis = subspace.row_basis(z, q)
    w = rng.poisson(1.0, N).astype(float)
    one = subspace.schur_from_data(basis, H, w, jobs=1)
    for jobs in (2, None):
        np.testing.assert_array_equal(subspace.schur_from_data(basis, H, w, jobs=jobs), one)
    # and it is the Schur complement of the whole data matrix
    U, Y = subspace.data_matrices(basis.values * np.sqrt(w)[None, :], H)
    Z = np.vstack([U, Y])
    G = (Z @ Z.conj().T).real
    m = q * nu
    whole = G[m:, m:] - G[m:, :m] @ np.linalg.solve(G[:m, :m], G[:m, m:])
    np.testing.assert_allclose(one, whole, rtol=0, atol=1e-10 * np.abs(whole).max())


@pytest.mark.parametrize("kind", ["monomial", "orthonormal"])
def test_basis_at_the_lines_is_the_basis(kind):
    """The recurrence run at the data points gives the basis's own values (scaled to
    ``p_0 = 1``), and far off the arc it stays finite."""
    z = np.exp(1j * np.linspace(0.3, 2.1, 300))
    basis = subspace.row_basis(z, 40, kind)
    P = subspace.basis_at(basis, z)
    np.testing.assert_allclose(P, basis.values.T / basis.p0, rtol=0, atol=1e-9 * np.abs(P).max())
    far = subspace.basis_at(subspace.row_basis(z, 400, kind), np.array([50.0 + 0j, -3.0j]))
    assert np.all(np.isfinite(far)) and np.all(np.abs(far[:, -1]) > 0)
    if kind == "monomial":  # the rescaling keeps every ratio
        kept = np.abs(far[0, :-1]) > 1e-200
        np.testing.assert_allclose(far[0, 1:][kept] / far[0, :-1][kept], 50.0, rtol=1e-12)


def test_a_mode_beyond_the_band_keeps_its_shape_at_many_block_rows():
    """Two outputs, a 4-mass chain whose fourth mode lies just above the band: its column of
    ``O`` lies in the last block rows at many block rows, and read off the first one its
    shape was wrong (noise-free misfit 7e-4 at the true order with 91 block rows). Fitted
    over every block row (``output_matrix``), the model of the true order is exact."""
    system = sim.damp(sim.chain(4), "rayleigh", zeta=0.01)
    fn = np.sort(sim.natural_frequencies_hz(system))
    freq = np.linspace(0.5 * fn[0], 0.5 * (fn[2] + fn[3]), 1500)
    data, _ = sim.simulate_test(system, [0, 2], [0], freq, "displacement", noise=0.0)
    w = 2 * np.pi * data.frequency
    T = bilinear.default_scale(w[0], w[-1])
    z = bilinear.to_unit_circle(w, T)
    H = data.frf / np.sqrt(np.mean(np.abs(data.frf) ** 2, axis=(0, 2)))[None, :, None]
    n = 8
    for q in (13, 91):
        basis = subspace.row_basis(z, q)
        O = subspace.observability(basis, H, n)[0]
        A, C_first = subspace.shift_invariance(O, 2, basis)
        eigen = np.linalg.eig(A)
        CV, C = subspace.output_matrix(O, *eigen, basis, 2)
        np.testing.assert_allclose(np.abs(CV).sum(axis=0) > 0, True)
        np.testing.assert_allclose(CV, C @ eigen[1], atol=1e-10)
        if q == 13:  # where the first block row holds every mode, the same vectors
            same = np.sum(CV.conj() * (C_first @ eigen[1]), axis=0)
            np.testing.assert_allclose(same.imag, 0.0, atol=1e-8 * np.abs(same).max())
            assert np.all(same.real > 0)
        B, D = subspace.estimate_bd(z, H, A, C, eigen=eigen)
        fit = D[None] + subspace.modal_sum(CV, eigen[0], np.linalg.solve(eigen[1], B), z)
        assert np.linalg.norm(fit - H) < 1e-7 * np.linalg.norm(H), q
    # the first block row's C at 91 rows: the misfit the scan saw (the test can fail)
    B, D = subspace.estimate_bd(z, H, A, C_first, eigen=eigen)
    fit = D[None] + subspace.modal_sum(C_first @ eigen[1], eigen[0],
                                       np.linalg.solve(eigen[1], B), z)
    assert np.linalg.norm(fit - H) > 1e-4 * np.linalg.norm(H)
