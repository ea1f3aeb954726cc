"""Bootstrap replicates: resampling weights and the identification of stacks of replicates.

A frequency-line replicate draws the ``N`` lines with replacement; line ``k`` then counts
``c_k`` times, which enters the Gram sums linearly, so all replicates' sums are one matrix
product (:func:`automodal.core.subspace.gram_sums` with a ``(B, N)`` weight matrix).
A record replicate draws whole repeated measurements and averages them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from automodal.core import subspace
from automodal.core.bilinear import poles_d2c
from automodal.core.modal import normalise_shapes, oscillatory_order


def line_weights(n_lines: int, n_bootstrap: int, rng: np.random.Generator) -> np.ndarray:
    """Multiplicities of each line in each replicate, ``(n_bootstrap, n_lines)`` integers.

    Each row is a multinomial draw of ``n_lines`` from ``n_lines`` equally likely lines.
    """
    return rng.multinomial(n_lines, np.full(n_lines, 1.0 / n_lines), size=n_bootstrap)


def record_weights(n_records: int, n_bootstrap: int, rng: np.random.Generator) -> np.ndarray:
    """Multiplicities of each record in each replicate, ``(n_bootstrap, n_records)``."""
    return rng.multinomial(n_records, np.full(n_records, 1.0 / n_records), size=n_bootstrap)


@dataclass
class ReplicateModes:
    """Oscillatory modes of one bootstrap model (``Im lambda > 0``)."""

    poles: np.ndarray  # (m,) continuous-time
    mu: np.ndarray  # (m,) discrete-time
    shapes: np.ndarray  # (ny, m) in scaled units, unit norm
    path: str  # "gram" or "qr"


def replicates_from_schur(
    S: np.ndarray,
    n: int,
    basis: subspace.RowBasis,
    T: float,
    ny: int,
    qr_fallback: Callable[[int], np.ndarray] | None = None,
    output_basis: np.ndarray | None = None,
) -> list[ReplicateModes]:
    """Identify ``A`` and ``C`` of a stack of replicates from their Schur complements, and
    their modes: one stacked ``eigh``, the normal-equation shift invariance, one stacked
    ``eig`` (each replicate is computed exactly as if alone, whatever the stack's size).

    Parameters
    ----------
    S : ndarray, shape (k, q ny, q ny)
        ``L22 L22^T`` of each replicate.
    n : int
        Model order.
    basis : RowBasis
        Row basis at the (full-data) lines.
    T : float
        Bilinear scale.
    ny : int
        Outputs of the data (the projected outputs when ``output_basis`` is given).
    qr_fallback : callable, optional
        ``qr_fallback(i)`` returns ``L22`` of replicate ``i`` of the stack on the QR path;
        when given, a replicate whose Gram-path subspace is not resolved
        (:func:`automodal.core.subspace.gram_resolves`) is recomputed from it.
    output_basis : ndarray, shape (ny_full, ny), optional
        The real orthonormal output directions the data were projected on
        (:func:`automodal.core.whitening.principal_outputs`): the shapes are returned in
        the full outputs, ``output_basis @ C psi``.

    Returns
    -------
    list of ReplicateModes
        One per replicate, in stack order; modes sorted by natural frequency.
    """
    O, sv = subspace.observability_from_schur(S, n)
    paths = ["gram"] * S.shape[0]
    if qr_fallback is not None:
        for i in range(S.shape[0]):
            if not subspace.gram_resolves(sv[i]):
                O[i] = subspace.observability_from_l22(qr_fallback(i), n)[0]
                paths[i] = "qr"
    A, _ = subspace.shift_invariance(O, ny, basis)
    mu, V = np.linalg.eig(A)
    mu = mu.astype(complex, copy=False)
    k, n_states = mu.shape
    # (k, ny, n): every replicate's shapes, normalised in one call
    psi = subspace.modal_outputs(O, mu, V, basis, ny)
    if output_basis is not None:
        psi = output_basis @ psi
    n_out = psi.shape[1]
    psi = normalise_shapes(psi.swapaxes(0, 1).reshape(n_out, k * n_states))
    psi = psi.reshape(n_out, k, n_states).swapaxes(0, 1)
    lam = poles_d2c(mu, T)
    out = []
    for i in range(k):
        sel = oscillatory_order(lam[i])
        out.append(ReplicateModes(poles=lam[i, sel], mu=mu[i, sel], shapes=psi[i][:, sel],
                                  path=paths[i]))
    return out
