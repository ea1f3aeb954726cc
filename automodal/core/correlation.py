"""The modal observability correlation (MOC) and correlation against subspaces.

The MOC vector of a mode with shape ``psi`` and discrete-time pole ``mu`` is the mode's
column of the observability matrix of the diagonal realisation,
``o = [psi; mu psi; ...; mu^(k-1) psi] / norm``. ``|o_i^H o_j|^2`` is the MAC of the shapes
times a kernel in the pole difference, so it separates modes whose shapes look alike at
few sensors (spatial aliasing). For a group of (near-)repeated modes, whose individual
eigenvectors are not unique, a mode is correlated with the group's subspace instead:
``rho(o, S) = ||Q_S^H o||^2``.
"""

from __future__ import annotations

import numpy as np


def moc_vectors(shapes: np.ndarray, mu: np.ndarray, k: int) -> np.ndarray:
    """Unit-norm MOC vectors ``W_k(mu) kron psi`` of each mode.

    Parameters
    ----------
    shapes : ndarray, shape (ny, m)
        Mode shapes (any scaling).
    mu : ndarray, shape (m,)
        Discrete-time poles (inside or near the unit circle).
    k : int
        Number of block rows (powers); use at least the identification's block rows so
        that the noise modes cannot span everything.

    Returns
    -------
    ndarray, shape (k ny, m)
    """
    shapes = np.asarray(shapes, dtype=complex)
    ny, m = shapes.shape
    powers = np.asarray(mu, dtype=complex)[None, :] ** np.arange(k)[:, None]  # (k, m)
    # ||W_k(mu) kron psi|| = ||W_k(mu)|| ||psi||: both factors normalised apart, so that the
    # (k ny, m) array is written once
    return (_unit_columns(powers)[:, None, :] * _unit_columns(shapes)[None, :, :]).reshape(
        k * ny, m)


def _unit_columns(x: np.ndarray) -> np.ndarray:
    """Columns divided by their norms (a zero column left as it is)."""
    norms = np.linalg.norm(x, axis=0)
    norms[~(norms > 0)] = 1.0
    return x / norms


def moc(o_a: np.ndarray, o_b: np.ndarray) -> np.ndarray:
    """MOC between unit-norm MOC vectors: ``|o_a^H o_b|^2`` for all column pairs."""
    return np.abs(np.asarray(o_a).conj().T @ np.asarray(o_b)) ** 2


def orthonormal_basis(vectors: np.ndarray, rtol: float = 1e-8) -> np.ndarray:
    """Orthonormal basis of the span of the columns (SVD with a relative rank tolerance).

    Returns
    -------
    ndarray, shape (dim, r)
        ``r = 0`` columns for an empty or zero set.
    """
    vectors = np.asarray(vectors, dtype=complex)
    if vectors.size == 0:
        return np.zeros((vectors.shape[0], 0), dtype=complex)
    u, s, _ = np.linalg.svd(vectors, full_matrices=False)
    if s.size == 0 or s[0] == 0:
        return np.zeros((vectors.shape[0], 0), dtype=complex)
    return u[:, s > rtol * s[0]]


def subspace_correlation(basis: np.ndarray, o: np.ndarray) -> np.ndarray:
    """``rho = ||Q^H o||^2`` of unit-norm vectors ``o`` (columns) with an orthonormal basis ``Q``.

    It is the squared cosine of the angle between each vector and the subspace, and equals
    the MOC when the subspace is one vector.
    """
    if basis.shape[1] == 0:
        return np.zeros(np.asarray(o).shape[1])
    return np.sum(np.abs(basis.conj().T @ o) ** 2, axis=0)


def subspace_correlations(bases: list[np.ndarray], o: np.ndarray) -> np.ndarray:
    """:func:`subspace_correlation` of the vectors ``o`` with each of several bases.

    One product with all the bases side by side: the vectors are read once, not once per
    basis (with thousands of bootstrap modes and a basis of one or two vectors per
    cluster, each separate product was a pass over all of ``o`` for a few rows).

    Returns
    -------
    ndarray, shape (len(bases), M)
        Row ``c``: the correlations with ``bases[c]`` (zeros for an empty basis).
    """
    o = np.asarray(o)
    dims = np.array([b.shape[1] for b in bases], dtype=int)
    out = np.zeros((dims.size, o.shape[1]))
    if dims.sum() == 0:
        return out
    power = np.abs(np.hstack(bases).conj().T @ o) ** 2
    ends = np.cumsum(dims)
    for c in np.flatnonzero(dims):
        out[c] = np.sum(power[ends[c] - dims[c] : ends[c]], axis=0)
    return out
