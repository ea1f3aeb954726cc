"""Unit tests of :mod:`automodal.core.correlation` on small hand-made arrays.

Every expected value is derived by hand in the test (or its comment), not recomputed
with the function under test.
"""

from __future__ import annotations

import numpy as np
import pytest

from automodal.core.correlation import (
    moc,
    moc_vectors,
    orthonormal_basis,
    subspace_correlation,
    subspace_correlations,
)

E = np.eye(4, dtype=complex)  # e_0 .. e_3 as columns


# ---------------------------------------------------------------------------------------
# moc_vectors
# ---------------------------------------------------------------------------------------


def test_moc_vector_of_one_mode_by_hand():
    # psi = [1, 2], mu = 0.5, k = 3: raw o = [1, 2, 0.5, 1, 0.25, 0.5],
    # |o|^2 = (1 + 4)(1 + 0.25 + 0.0625) = 6.5625
    o = moc_vectors(np.array([[1.0], [2.0]]), np.array([0.5]), 3)
    raw = np.array([1.0, 2.0, 0.5, 1.0, 0.25, 0.5])
    assert o.shape == (6, 1)
    np.testing.assert_allclose(o[:, 0], raw / np.sqrt(6.5625), rtol=1e-14)


def test_moc_vectors_shape_unit_norm_and_block_structure():
    rng = np.random.default_rng(1)
    ny, m, k = 3, 4, 5
    shapes = rng.normal(size=(ny, m)) + 1j * rng.normal(size=(ny, m))
    mu = np.array([0.9 * np.exp(0.3j), 0.5 * np.exp(2.0j), 0.99 * np.exp(-1.0j), 0.2])
    o = moc_vectors(shapes, mu, k)
    assert o.shape == (k * ny, m)  # k row blocks of ny rows, one column per mode
    np.testing.assert_allclose(np.linalg.norm(o, axis=0), 1.0, rtol=1e-13)
    for i in range(m):
        first = o[:ny, i]
        # the first block is the (scaled) shape itself: parallel to psi, not conjugated
        ratio = first / shapes[:, i]
        np.testing.assert_allclose(ratio, ratio[0], rtol=1e-12)
        assert abs(ratio[0].imag) < 1e-12 and ratio[0].real > 0
        # block j is mu^j times block 0 (rows ordered power-major, not sensor-major)
        for j in range(1, k):
            np.testing.assert_allclose(
                o[j * ny : (j + 1) * ny, i], mu[i] ** j * first, rtol=1e-12, atol=1e-15
            )


def test_moc_vectors_k1_is_the_normalised_shape():
    psi = np.array([[3.0, 0.0], [4.0, 2j]])
    o = moc_vectors(psi, np.array([0.3, -0.7]), 1)
    np.testing.assert_allclose(o, np.array([[0.6, 0.0], [0.8, 1j]]), rtol=1e-15)


def test_moc_vectors_zero_shape_gives_zero_column_not_nan():
    shapes = np.array([[0.0, 1.0], [0.0, 0.0]])
    o = moc_vectors(shapes, np.array([0.5, 0.5]), 2)
    assert np.all(np.isfinite(o))
    np.testing.assert_array_equal(o[:, 0], 0.0)
    assert np.linalg.norm(o[:, 1]) == pytest.approx(1.0)


def test_moc_vectors_ignore_shape_scaling():
    psi = np.array([[1.0], [-2.0], [0.5]])
    mu = np.array([0.8 * np.exp(0.4j)])
    a = moc_vectors(psi, mu, 4)
    b = moc_vectors((-3.0 + 4.0j) * psi, mu, 4)
    # same vector up to a unit phase: MOC 1
    assert moc(a, b)[0, 0] == pytest.approx(1.0, abs=1e-14)


# ---------------------------------------------------------------------------------------
# moc = MAC x pole kernel
# ---------------------------------------------------------------------------------------


def test_moc_of_identical_modes_is_one():
    psi = np.array([[1.0 + 1j], [2.0], [-0.5j]])
    mu = np.array([0.95 * np.exp(0.7j)])
    o = moc_vectors(psi, mu, 6)
    assert moc(o, o)[0, 0] == pytest.approx(1.0, abs=1e-14)


def test_moc_of_orthogonal_shapes_is_zero_whatever_the_poles():
    shapes = np.array([[1.0, 1.0], [1.0, -1.0]])
    for mu in ([0.9, 0.9], [0.9, 0.1j]):
        o = moc_vectors(shapes, np.array(mu, dtype=complex), 5)
        assert moc(o[:, :1], o[:, 1:])[0, 0] == pytest.approx(0.0, abs=1e-14)


def test_moc_kernel_two_block_rows_is_cos_squared_of_half_angle():
    # same shape, mu_a = 1, mu_b = e^{i theta}, k = 2:
    # |1 + e^{i theta}|^2 / (2 * 2) = (2 + 2 cos theta) / 4 = cos^2(theta / 2)
    psi = np.array([[1.0], [0.0]])
    for theta in (0.0, 0.3, 1.0, np.pi / 2, 2.0, np.pi):
        oa = moc_vectors(psi, np.array([1.0 + 0j]), 2)
        ob = moc_vectors(psi, np.array([np.exp(1j * theta)]), 2)
        assert moc(oa, ob)[0, 0] == pytest.approx(np.cos(theta / 2) ** 2, abs=1e-14)


def test_moc_same_shape_decreases_with_pole_distance():
    psi = np.array([[1.0], [2.0], [3.0]])
    mu0 = 0.95 * np.exp(1.0j)
    o0 = moc_vectors(psi, np.array([mu0]), 8)
    values = [
        moc(o0, moc_vectors(psi, np.array([0.95 * np.exp(1j * (1.0 + d))]), 8))[0, 0]
        for d in (0.0, 0.01, 0.05, 0.1, 0.2)
    ]
    assert values[0] == pytest.approx(1.0, abs=1e-14)
    assert np.all(np.diff(values) < 0)
    assert values[-1] < 0.9


def test_moc_factors_into_mac_times_kernel():
    rng = np.random.default_rng(7)
    ny, k = 4, 6
    psi = rng.normal(size=(ny, 3)) + 1j * rng.normal(size=(ny, 3))
    mu = np.array([0.9 * np.exp(0.5j), 0.8 * np.exp(0.6j), 0.95 * np.exp(-2.0j)])
    got = moc(moc_vectors(psi, mu, k), moc_vectors(psi, mu, k))
    for a in range(3):
        for b in range(3):
            pa, pb = psi[:, a], psi[:, b]
            mac = abs(np.vdot(pa, pb)) ** 2 / (np.vdot(pa, pa).real * np.vdot(pb, pb).real)
            wa, wb = mu[a] ** np.arange(k), mu[b] ** np.arange(k)
            kern = abs(np.vdot(wa, wb)) ** 2 / (np.vdot(wa, wa).real * np.vdot(wb, wb).real)
            assert got[a, b] == pytest.approx(mac * kern, rel=1e-12)


def test_moc_matrix_shape_and_symmetry():
    o_a = np.column_stack([E[:, 0], (E[:, 0] + E[:, 1]) / np.sqrt(2)])
    o_b = np.column_stack([E[:, 0], E[:, 1], E[:, 2]])
    m = moc(o_a, o_b)
    assert m.shape == (2, 3)  # rows: o_a's columns, columns: o_b's
    np.testing.assert_allclose(m, [[1.0, 0.0, 0.0], [0.5, 0.5, 0.0]], atol=1e-15)
    np.testing.assert_allclose(moc(o_b, o_a), m.T, atol=1e-15)


# ---------------------------------------------------------------------------------------
# orthonormal_basis
# ---------------------------------------------------------------------------------------


def test_orthonormal_basis_detects_rank_and_is_orthonormal():
    v = np.column_stack([E[:, 0], E[:, 1], E[:, 0] + 2j * E[:, 1]])  # rank 2 in C^4
    q = orthonormal_basis(v)
    assert q.shape == (4, 2)
    np.testing.assert_allclose(q.conj().T @ q, np.eye(2), atol=1e-14)
    # spans the inputs: projecting each input onto q gives it back
    np.testing.assert_allclose(q @ (q.conj().T @ v), v, atol=1e-14)
    # and nothing of e_2, e_3
    np.testing.assert_allclose(q[2:], 0.0, atol=1e-15)


def test_orthonormal_basis_relative_tolerance():
    v = np.column_stack([E[:, 0], 1e-10 * E[:, 1]])  # singular values 1 and 1e-10
    assert orthonormal_basis(v).shape[1] == 1  # default rtol 1e-8: the tiny one is noise
    assert orthonormal_basis(v, rtol=1e-12).shape[1] == 2
    # relative, not absolute: scaling the whole set changes nothing
    assert orthonormal_basis(1e-20 * v).shape[1] == 1
    assert orthonormal_basis(1e20 * v, rtol=1e-12).shape[1] == 2


def test_orthonormal_basis_tolerance_is_strict():
    v = np.column_stack([E[:, 0], 0.5 * E[:, 1]])  # singular values 1 and 0.5 exactly
    assert orthonormal_basis(v, rtol=0.5).shape[1] == 1  # s > rtol * s0, not >=
    assert orthonormal_basis(v, rtol=0.4999).shape[1] == 2


@pytest.mark.parametrize(
    "vectors", [np.zeros((4, 0)), np.zeros((4, 3))], ids=["empty", "all-zero"]
)
def test_orthonormal_basis_of_nothing_has_no_columns(vectors):
    q = orthonormal_basis(vectors)
    assert q.shape == (4, 0)


def test_orthonormal_basis_accepts_real_input():
    q = orthonormal_basis(np.array([[2.0], [0.0]]))
    assert q.shape == (2, 1)
    assert abs(abs(q[0, 0]) - 1.0) < 1e-15 and q[1, 0] == 0


# ---------------------------------------------------------------------------------------
# subspace_correlation
# ---------------------------------------------------------------------------------------


def _plane() -> np.ndarray:
    return orthonormal_basis(np.column_stack([E[:, 0], E[:, 1]]))


def test_subspace_correlation_in_span_orthogonal_and_45_degrees():
    o = np.column_stack(
        [
            (E[:, 0] + 1j * E[:, 1]) / np.sqrt(2),  # in the span
            E[:, 2],  # orthogonal
            (E[:, 0] + E[:, 3]) / np.sqrt(2),  # 45 degrees to the plane
            (np.sqrt(3) * E[:, 1] + E[:, 2]) / 2,  # 30 degrees: cos^2 = 3/4
        ]
    )
    rho = subspace_correlation(_plane(), o)
    np.testing.assert_allclose(rho, [1.0, 0.0, 0.5, 0.75], atol=1e-14)


def test_subspace_correlation_does_not_depend_on_the_basis_chosen():
    o = np.array([[0.6], [0.0], [0.8j], [0.0]])
    b1 = _plane()
    b2 = orthonormal_basis(np.column_stack([E[:, 0] + E[:, 1], E[:, 0] - 2j * E[:, 1]]))
    np.testing.assert_allclose(subspace_correlation(b1, o), [0.36], atol=1e-14)
    np.testing.assert_allclose(subspace_correlation(b2, o), [0.36], atol=1e-14)


def test_subspace_correlation_of_one_vector_equals_moc():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(5, 1)) + 1j * rng.normal(size=(5, 1))
    a /= np.linalg.norm(a)
    o = rng.normal(size=(5, 4)) + 1j * rng.normal(size=(5, 4))
    o /= np.linalg.norm(o, axis=0)
    np.testing.assert_allclose(subspace_correlation(a, o), moc(a, o)[0], rtol=1e-12)


def test_subspace_correlation_with_empty_basis_is_zero():
    rho = subspace_correlation(np.zeros((4, 0), dtype=complex), E[:, :3])
    assert rho.shape == (3,)
    np.testing.assert_array_equal(rho, 0.0)


def test_subspace_correlations_are_each_bases_own():
    # one product for all the bases: the same numbers as one basis at a time, an empty
    # basis giving zeros; the plane and the line by hand
    o = np.column_stack([(E[:, 0] + E[:, 3]) / np.sqrt(2), E[:, 2], E[:, 1]])
    line = E[:, 3:4]
    empty = np.zeros((4, 0), dtype=complex)
    rho = subspace_correlations([_plane(), empty, line], o)
    np.testing.assert_allclose(rho, [[0.5, 0.0, 1.0], [0.0, 0.0, 0.0], [0.5, 0.0, 0.0]],
                               atol=1e-15)
    assert subspace_correlations([empty], o).shape == (1, 3)
    assert subspace_correlations([], o).shape == (0, 3)
