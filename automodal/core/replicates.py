"""Running the bootstrap replicates: chunks of stacked small problems on worker threads.

Frequency-line replicates share one batched Gram product
(:func:`automodal.core.subspace.gram_sums`); record replicates each average a resample of
the repeated records. Either way each chunk of replicates is one stacked Schur complement,
``eigh``, shift invariance and ``eig`` (:func:`automodal.core.bootstrap.replicates_from_schur`).
The chunks are fixed by the problem's size and combined in chunk order, each computed
with one BLAS thread, so the result never depends on the number of workers.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from automodal.core import bootstrap, subspace
from automodal.core.parallel import freeing_map, gather, worker_count
from automodal.core.pole_map import PoleMap
from automodal.errors import InputError

REPLICATE_CHUNK_BYTES = 32 * 2**20
"""Memory for the stacked arrays of one chunk of replicates (Schur complements,
eigenvectors, ``A``, complex eigenvectors): bounds the memory whatever ``B``."""


def replicate_chunks(n_replicates: int, m: int, n: int) -> list[range]:
    """Chunks of replicates computed by one stacked call each.

    The size depends only on the problem (never on the number of workers), so results
    cannot depend on ``jobs``: at most a quarter of the replicates (so two workers share
    the load) and :data:`REPLICATE_CHUNK_BYTES` of stacked arrays.
    """
    per = 8.0 * (3 * m * m + 6 * n * n + 2 * m * n)
    size = max(1, min(math.ceil(n_replicates / 4), int(REPLICATE_CHUNK_BYTES // per)))
    return [range(i, min(n_replicates, i + size)) for i in range(0, n_replicates, size)]


def replicate_flops(m: int, n: int) -> float:
    """Rough floating-point work of one replicate: eigh of ``m x m``, eig of ``n x n``."""
    return 9.0 * m**3 + 25.0 * n**3


def _line_replicates_flops(
    basis: subspace.RowBasis, H: np.ndarray, n: int, n_replicates: int
) -> float:
    """Work of :func:`run_replicates`: the Gram product and the replicates' eigenproblems."""
    N, ny, nu = H.shape
    m = basis.q * ny
    return replicate_flops(m, n) * n_replicates + 4.0 * n_replicates * N * m * (ny + nu)


def replicate_workers(
    jobs: int | None, basis: subspace.RowBasis, H: np.ndarray, n: int, n_replicates: int
) -> int:
    """Worker threads :func:`run_replicates` starts with: ``jobs`` if given, else all the
    free cores when the Gram product and the replicates' eigenproblems pay for them."""
    return worker_count(jobs, n_replicates, _line_replicates_flops(basis, H, n, n_replicates))


def run_replicates(
    basis: subspace.RowBasis,
    H: np.ndarray,
    n: int,
    T: float,
    weights: np.ndarray,
    jobs: int | None,
    progress: Callable[[int], None] | None = None,
    output_basis: np.ndarray | None = None,
) -> list[bootstrap.ReplicateModes]:
    """All frequency-line replicates' modes: one batched Gram product, then stacked small
    problems, in ``jobs`` threads (``None``: the free cores, and any core freed while they
    run, :func:`automodal.core.parallel.freeing_map`).

    Parameters
    ----------
    basis : RowBasis
        Row basis of the reference model at the analysed lines.
    H : ndarray, shape (N, ny, nu)
        FRF, channel-scaled.
    n : int
        Model order.
    T : float
        Bilinear scale.
    weights : ndarray, shape (B, N)
        Line weights of each replicate (bootstrap counts times the line weights).
    jobs : int or None
        Worker threads.
    progress : callable, optional
        Called with the number of replicates finished since the last call.
    output_basis : ndarray, shape (ny, r), optional
        Real orthonormal output directions the replicates identify on
        (:func:`automodal.core.whitening.principal_outputs`): ``H`` is projected on them
        (:func:`project_outputs`) and the shapes come back in every output
        (:func:`automodal.core.bootstrap.replicates_from_schur`).
    """
    if output_basis is not None:
        H = project_outputs(H, output_basis)
    B = weights.shape[0]
    ny = H.shape[1]
    m = basis.q * ny

    def work(r: range) -> list[bootstrap.ReplicateModes]:
        S = subspace.schur_complement(sums, slice(r.start, r.stop))
        return bootstrap.replicates_from_schur(
            S, n, basis, T, ny,
            qr_fallback=lambda i: subspace.projected_output_qr(basis, H, weights[r.start + i]),
            output_basis=output_basis,
        )

    chunks = replicate_chunks(B, m, n)
    with freeing_map(jobs, B, _line_replicates_flops(basis, H, n, B)) as (_, pmap):
        sums = subspace.gram_sums(basis, H, weights, map_fn=pmap)
        return gather(pmap(work, chunks), chunks, progress)


def run_record_replicates(
    basis: subspace.RowBasis,
    records: np.ndarray,
    n: int,
    T: float,
    weights: np.ndarray,
    line_weights: np.ndarray,
    jobs: int | None,
    progress: Callable[[int], None] | None = None,
    output_basis: np.ndarray | None = None,
) -> list[bootstrap.ReplicateModes]:
    """Replicates that each average a resample of the repeated records.

    The Gram sums are not linear in the FRF, so each replicate forms its own Schur
    complement; the rest is stacked as in :func:`run_replicates`, and likewise the result
    does not depend on ``jobs``.

    Parameters
    ----------
    records : ndarray, shape (R, N, ny, nu)
        Repeated records over the analysed lines, channel-scaled.
    weights : ndarray, shape (B, R)
        Record multiplicities of each replicate.
    line_weights : ndarray, shape (N,)
        Line weights of every replicate's fit.
    basis, n, T, jobs, progress, output_basis
        As in :func:`run_replicates`.
    """
    if output_basis is not None:
        records = project_outputs(records, output_basis)

    def average(b: int) -> np.ndarray:
        return np.einsum("r,rkij->kij", weights[b] / weights[b].sum(), records)

    return _own_schur_replicates(
        average, weights.shape[0], records.shape[2], basis, n, T, line_weights, jobs, progress,
        output_basis,
    )


def _own_schur_replicates(
    frf_of: Callable[[int], np.ndarray],
    n_replicates: int,
    ny: int,
    basis: subspace.RowBasis,
    n: int,
    T: float,
    line_weights: np.ndarray,
    jobs: int | None,
    progress: Callable[[int], None] | None,
    output_basis: np.ndarray | None = None,
) -> list[bootstrap.ReplicateModes]:
    """Replicates whose FRFs ``frf_of(b)`` each form their own Schur complement (the Gram
    sums are not linear in the FRF), stacked per chunk as in :func:`run_replicates`; the
    result does not depend on ``jobs``."""
    m = basis.q * ny

    def work(r: range) -> list[bootstrap.ReplicateModes]:
        Hb = [frf_of(b) for b in r]
        S = np.stack([subspace.single_schur(basis, h, line_weights) for h in Hb])
        return bootstrap.replicates_from_schur(
            S, n, basis, T, ny,
            qr_fallback=lambda i: subspace.projected_output_qr(basis, Hb[i], line_weights),
            output_basis=output_basis,
        )

    chunks = replicate_chunks(n_replicates, m, n)
    with freeing_map(jobs, n_replicates, replicate_flops(m, n) * n_replicates) as (_, pmap):
        return gather(pmap(work, chunks), chunks, progress)


def run_noise_replicates(
    basis: subspace.RowBasis,
    H_model: np.ndarray,
    variance: np.ndarray,
    n: int,
    T: float,
    seeds: np.ndarray,
    line_weights: np.ndarray,
    jobs: int | None,
    progress: Callable[[int], None] | None = None,
    output_basis: np.ndarray | None = None,
) -> list[bootstrap.ReplicateModes]:
    """Parametric replicates: the reference model's FRF plus fresh noise of the noise model.

    Replicate ``b`` identifies ``H_model + e_b`` with ``e_b`` complex Gaussian of variance
    ``variance`` per line and entry (real and imaginary parts ``variance / 2`` each),
    drawn from ``numpy.random.default_rng(seeds[b])``: the spread then reflects the noise
    itself rather than one realization of it. Like :func:`run_record_replicates`, each
    replicate forms its own Schur complement; the result does not depend on ``jobs``.

    Parameters
    ----------
    H_model : ndarray, shape (N, ny, nu)
        The reference model's FRF at the analysed lines (channel-scaled); with
        ``output_basis`` each replicate's noise is drawn on every output, then projected.
    variance : ndarray, shape (N, ny, nu)
        Noise variance in the same units.
    seeds : ndarray of int, shape (B,)
        One seed per replicate.
    line_weights : ndarray, shape (N,)
        Line weights of every replicate's fit.
    basis, n, T, jobs, progress, output_basis
        As in :func:`run_replicates`.
    """
    std = np.sqrt(np.asarray(variance, float) / 2.0)

    def draw(b: int) -> np.ndarray:
        g = np.random.default_rng(int(seeds[b])).standard_normal((2,) + H_model.shape)
        Hb = H_model + std * (g[0] + 1j * g[1])
        # the noise drawn on every output, then projected: its projection is correlated
        return Hb if output_basis is None else project_outputs(Hb, output_basis)

    ny = H_model.shape[1] if output_basis is None else output_basis.shape[1]
    return _own_schur_replicates(
        draw, len(seeds), ny, basis, n, T, line_weights, jobs, progress, output_basis,
    )


def project_outputs(H: np.ndarray, output_basis: np.ndarray) -> np.ndarray:
    """``output_basis^T H`` line by line: ``(..., N, ny, nu)`` to ``(..., N, r, nu)``."""
    return np.einsum("ek,...ej->...kj", output_basis, H)


def band_records(
    records: np.ndarray | None,
    frequency: np.ndarray,
    band_frequency: np.ndarray,
    reciprocal: bool,
    resample: str,
    source: str | None = None,
) -> np.ndarray | None:
    """The repeated records over the analysed lines (oriented like the analysed FRF), or
    ``None`` when the replicates resample frequency lines.

    Parameters
    ----------
    records : ndarray, shape (R, N_all, ny, nu) or None
        The data's repeated records.
    frequency : ndarray, shape (N_all,)
        The data's lines (Hz).
    band_frequency : ndarray
        The analysed lines (Hz), a subset of ``frequency``.
    reciprocal : bool
        Whether inputs and outputs were swapped (the records are transposed likewise).
    resample : {"auto", "lines", "records", "noise"}
        What the replicates resample (``"auto"``: records when there are two or more;
        ``"noise"``: never records).
    source : str, optional
        The data's file, named in errors.
    """
    if resample not in ("auto", "lines", "records", "noise"):
        raise ValueError(f"unknown resample {resample!r}")
    usable = records is not None and records.shape[0] >= 2
    if resample == "records" and not usable:
        raise InputError("resampling records needs at least two records (/records/frf)",
                         source)
    if resample in ("lines", "noise") or not usable:
        return None
    rec = records[:, np.isin(frequency, band_frequency)]
    return np.ascontiguousarray(rec.transpose(0, 1, 3, 2)) if reciprocal else rec


@dataclass
class ReplicatePoles:
    """The oscillatory modes of all replicates, stacked.

    Attributes
    ----------
    poles : ndarray, shape (M,)
        Continuous-time poles (rad/s).
    mu : ndarray, shape (M,)
        Discrete-time poles.
    shapes : ndarray, shape (ny, M)
        Mode shapes in scaled units, unit norm.
    replicate : ndarray of int, shape (M,)
        Replicate of each pole.
    n_qr : int
        Replicates computed on the QR path.
    """

    poles: np.ndarray
    mu: np.ndarray
    shapes: np.ndarray
    replicate: np.ndarray
    n_qr: int


def stack_replicates(
    reps: list[bootstrap.ReplicateModes], ny: int, pole_map: PoleMap | None = None
) -> ReplicatePoles:
    """All replicates' modes in one set of arrays, their poles the structure's
    (``pole_map`` applied, see :meth:`automodal.core.modal_model.ModalModel.modes`)."""
    if not reps:
        empty = np.zeros(0, complex)
        return ReplicatePoles(poles=empty, mu=empty, shapes=np.zeros((ny, 0), complex),
                              replicate=np.zeros(0, int), n_qr=0)
    replicate = np.concatenate([np.full(len(r.poles), b) for b, r in enumerate(reps)])
    poles = np.concatenate([r.poles for r in reps])
    if pole_map is not None:
        poles = pole_map(poles)
    mu = np.concatenate([r.mu for r in reps])
    shapes = np.hstack([r.shapes for r in reps])
    return ReplicatePoles(poles=poles, mu=mu, shapes=shapes, replicate=replicate.astype(int),
                          n_qr=sum(r.path == "qr" for r in reps))
