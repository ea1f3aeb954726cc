"""Bootstrap replicates: resampling weights and the identification of one replicate.

A frequency-line replicate draws the ``N`` lines with replacement; line ``k`` then counts
``c_k`` times, which enters the Gram sums linearly, so all replicates' sums are one matrix
product (:func:`automodal.core.subspace.gram_sums` with a ``(B, N)`` weight matrix).
A record replicate draws whole repeated measurements and averages them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from automodal.core import subspace
from automodal.core.modal import modes_of_discrete


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


def replicate_from_schur(
    S: np.ndarray,
    n: int,
    basis: subspace.RowBasis,
    T: float,
    ny: int,
    qr_data: tuple[np.ndarray, np.ndarray | None] | None = None,
) -> ReplicateModes:
    """Identify ``A`` and ``C`` of one replicate from its Schur complement, and its modes.

    Parameters
    ----------
    S : ndarray
        ``L22 L22^T`` of the replicate.
    n : int
        Model order.
    basis : RowBasis
        Row basis at the (full-data) lines.
    T : float
        Bilinear scale.
    ny : int
        Outputs.
    qr_data : (H, weights), optional
        Scaled FRF and the replicate's line weights: when given and the Gram path cannot
        resolve the subspace (:func:`automodal.core.subspace.gram_resolves`), the
        replicate is recomputed on the QR path.
    """
    O, sv = subspace.observability_from_schur(S, n)
    path = "gram"
    if qr_data is not None and not subspace.gram_resolves(sv):
        H, w = qr_data
        O, _ = subspace.observability_from_l22(subspace.projected_output_qr(basis, H, w), n)
        path = "qr"
    A, C = subspace.shift_invariance(O, ny, basis)
    ms = modes_of_discrete(A, C, T)
    return ReplicateModes(poles=ms.poles, mu=ms.mu, shapes=ms.shapes, path=path)
