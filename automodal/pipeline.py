"""The automated pipeline: from an :class:`FRFData` to identified modes with physicalness.

Steps (``method.md`` sections 1-6): band and scaling; order scan and the excessive
reference order; reference model and its two subspaces; bootstrap replicates (A and C
only, batched Gram sums, stacked small problems in parallel threads); one-pass assignment
with a Trashbox; trimming; three features per cluster and anchored fuzzy c-means;
per-cluster statistics.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from automodal import __version__
from automodal.core import bootstrap, checks, clustering, order, physicalness, subspace
from automodal.core.bilinear import default_scale, poles_d2c, to_unit_circle
from automodal.core.correlation import moc_vectors
from automodal.core.from_time import as_frfdata
from automodal.core.modal import ModeSet, modes_of_discrete, mpc, normalise_shapes, unit_max_shapes
from automodal.errors import InputError
from automodal.frfdata import FRFData

BOOTSTRAP_LINE_FRACTION = 0.6
"""Unique lines in a frequency-line replicate are about 63 % of all lines: the order is
limited so that a replicate still has enough (``2 * 0.6 N nu >= q (nu + ny)``)."""


MAX_SCAN_ORDER = 240
"""Highest order of the automatic misfit scan (``--order`` can set a lower limit)."""

MAX_REFERENCE_ORDER = 320
"""Highest automatic reference order: each replicate costs ``O(n^3)``, and at 320 states 100
replicates take several seconds on two cores. ``--order`` can raise it."""


@dataclass
class Settings:
    """Every parameter that influences a run (all have automatic defaults).

    Attributes
    ----------
    band_hz : (float, float) or None
        Analysed band; default the data's span (a 0 Hz line is left out).
    n_bootstrap : int
        Bootstrap replicates.
    seed : int
        Seed of the resampling; the same seed gives the same result whatever ``jobs``.
    max_order : int or None
        Largest model order (states) considered; default what the data allow.
    jobs : int or None
        Worker threads for the replicates; default all cores.
    threshold : float
        ``tau_1``, the correlation a mode needs to join a cluster.
    zeta_max : float
        Largest damping ratio of a physical candidate.
    min_physicalness : float
        Physicalness from which a cluster is called physical.
    coalescence : float
        Poles closer than this many half-power bandwidths form one group.
    resample : {"auto", "lines", "records"}
        What a bootstrap replicate resamples: the repeated records when the data have
        at least two (``"auto"``), or the frequency lines.
    """

    band_hz: tuple[float, float] | None = None
    n_bootstrap: int = 100
    seed: int = 0
    max_order: int | None = None
    jobs: int | None = None
    threshold: float = 0.8
    zeta_max: float = 0.2
    min_physicalness: float = 0.5
    coalescence: float = 1.0
    resample: str = "auto"

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form (``jobs`` left out: it never changes the result)."""
        d = dataclasses.asdict(self)
        d.pop("jobs")
        if d["band_hz"] is not None:
            d["band_hz"] = [float(x) for x in d["band_hz"]]
        return d


@dataclass
class IdentifiedMode:
    """One reported mode: a cluster (or one member rank of a near-repeated cluster)."""

    id: int
    frequency_hz: float
    frequency_std_hz: float
    frequency_ci95_hz: tuple[float, float]
    damping_ratio: float
    damping_std: float
    damping_ci95: tuple[float, float]
    physicalness: float
    physical: bool
    n_members: int
    mode_shape: np.ndarray
    mode_shape_std: np.ndarray
    mpc: float
    cluster: int
    cluster_dim: int
    features: dict[str, float]


@dataclass
class PoleTable:
    """Every bootstrap pole, for plots: cluster ``-1`` is the Trashbox."""

    frequency_hz: np.ndarray
    damping_ratio: np.ndarray
    cluster: np.ndarray
    replicate: np.ndarray


@dataclass
class Result:
    """The outcome of one run of the pipeline."""

    modes: list[IdentifiedMode]
    trashbox_members: int
    n_clusters: int
    settings: dict[str, Any]
    warnings: list[str]
    poles: PoleTable
    band_hz: tuple[float, float]
    orders: dict[str, Any]
    runtime_s: float
    automodal_version: str = __version__
    reference_model: subspace.StateSpaceModel | None = field(default=None, repr=False)
    reciprocity: bool = False
    shape_channels: list[str] = field(default_factory=list)
    n_lines: int = 0
    frf_fit: tuple[np.ndarray, np.ndarray, np.ndarray] | None = field(default=None, repr=False)
    """``(frequency_hz, measured, synthesized)`` over the analysed band, in the input's
    orientation (lines x outputs x inputs); synthesized from the physical modes."""

    @property
    def physical_modes(self) -> list[IdentifiedMode]:
        """The modes called physical."""
        return [m for m in self.modes if m.physical]


# ---------------------------------------------------------------------------------------
# Pieces
# ---------------------------------------------------------------------------------------


def select_band(
    data: FRFData, band_hz: tuple[float, float] | None, warnings: list[str]
) -> tuple[np.ndarray, np.ndarray, tuple[float, float]]:
    """Lines of the analysed band (a 0 Hz line is always left out)."""
    f = data.frequency
    lo, hi = (float(f[0]), float(f[-1])) if band_hz is None else map(float, band_hz)
    if band_hz is not None and not (0 <= lo < hi):
        raise InputError(f"band {lo:g}-{hi:g} Hz is not a valid band", data.source)
    keep = (f >= lo) & (f <= hi) & (f > 0)
    if band_hz is None and f[0] == 0:
        warnings.append("the 0 Hz line was left out of the analysis")
    if not keep.any():
        raise InputError(f"no frequency line in the band {lo:g}-{hi:g} Hz", data.source)
    fk = f[keep]
    return fk, data.frf[keep], (float(fk[0]), float(fk[-1]))


def order_limit(n_lines: int, ny: int, nu: int) -> int:
    """Largest even order the data allow, bootstrap replicates included."""
    budget = 2.0 * BOOTSTRAP_LINE_FRACTION * n_lines * nu
    n = 2
    while True:
        nxt = n + 2
        q = subspace.block_rows(nxt, ny)
        if q * (nu + ny) > budget or nxt > 2000:
            return n if subspace.block_rows(n, ny) * (nu + ny) <= budget else 0
        n = nxt


def count_peaks(H: np.ndarray, window: int = 5) -> int:
    """Resonance-like peaks of the mean magnitude over channels (sizes the order scan).

    A line counts when it is the largest within ``window`` lines on either side and stands
    above the smallest value there by more than the threshold: ``max(0.5, 6 s)`` on the
    natural-log scale, with ``s`` the line-to-line roughness of the log magnitude (robust:
    median absolute second difference). On pure noise the roughness is large and few
    "peaks" count, which keeps the scan short.
    """
    from scipy.ndimage import maximum_filter1d, minimum_filter1d

    mag = np.mean(np.abs(H), axis=(1, 2))
    if not np.any(mag > 0):
        return 0
    logm = np.log(np.maximum(mag, np.max(mag) * 1e-12))
    rough = 1.4826 * np.median(np.abs(np.diff(logm, 2))) / np.sqrt(6.0) if logm.size > 2 else 0.0
    thr = max(0.5, 6.0 * rough)
    size = 2 * window + 1
    is_max = logm >= maximum_filter1d(logm, size, mode="nearest")
    rise = logm - minimum_filter1d(logm, 8 * size, mode="nearest")
    return int(np.count_nonzero(is_max & (rise > thr)))


def scan_orders(n_scan: int) -> np.ndarray:
    """Orders of the misfit scan: every even order to 60, then steps of 4, then of 8 above 120."""
    orders = [n for n in range(2, min(n_scan, 60) + 1, 2)]
    orders += [n for n in range(64, min(n_scan, 120) + 1, 4)]
    orders += [n for n in range(128, n_scan + 1, 8)]
    return np.array(orders, dtype=int)


def scan(
    z: np.ndarray, H: np.ndarray, weights: np.ndarray, n_max: int, n_peaks: int
) -> tuple[np.ndarray, np.ndarray]:
    """The misfit scan, in stages: up to ``max(2 n_peaks + 40, 60)`` states first, and
    twice as far (with the block rows that order needs) while the misfit still falls at
    the end of a stage (:func:`automodal.core.order.still_falling`), up to ``n_max``. Small systems pay only for a small projection;
    systems with many overlapping modes (80 modes, 22 visible peaks) still reach their order.
    """
    N, ny, nu = H.shape
    while n_max > 4 and subspace.scan_block_rows(n_max, ny) * (nu + ny) > 2 * N * nu:
        n_max -= 2  # the scan's larger block rows must fit the (full) data too
    stage = min(n_max, max(2 * n_peaks + 40, 60))
    while True:
        planned = scan_orders(max(4, stage))
        basis = subspace.row_basis(z, subspace.scan_block_rows(int(planned[-1]), ny))
        orders, misfit = order.misfit_scan(
            z, H, planned, basis, weights=weights, stop_after=2 * n_peaks + 40
        )
        if orders.size < planned.size or stage >= n_max or not order.still_falling(
            orders, misfit
        ):
            return orders, misfit
        stage = min(n_max, 2 * stage)


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


@contextmanager
def _workers(n_jobs: int) -> Iterator[Callable[..., Iterator[Any]]]:
    """A ``map`` over ``n_jobs`` threads (the built-in ``map`` for one), with one BLAS
    thread: numpy's matrix products and stacked LAPACK calls release the GIL, so threads
    share the cores without starting processes (and without OpenBLAS's own threads, which
    spin after a product and slowed the next step by 10-25 %)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1):
        if n_jobs == 1:
            yield map
            return
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=n_jobs) as pool:
            yield pool.map


def _collect(
    parts: Iterable[list[bootstrap.ReplicateModes]],
    chunks: list[range],
    progress: Callable[[int], None] | None,
) -> list[bootstrap.ReplicateModes]:
    """Results of the chunks, in chunk order, reporting progress as they arrive."""
    results: list[bootstrap.ReplicateModes] = []
    for r, part in zip(chunks, parts):
        results.extend(part)
        if progress:
            progress(len(r))
    return results


def run_replicates(
    basis: subspace.RowBasis,
    H: np.ndarray,
    n: int,
    T: float,
    weights: np.ndarray,
    jobs: int | None,
    progress: Callable[[int], None] | None = None,
) -> list[bootstrap.ReplicateModes]:
    """All replicates' models: one batched Gram product, then stacked small problems.

    The Gram sums of every replicate are one matrix product (over chunks of lines); each
    chunk of replicates then takes one stacked Schur complement, ``eigh``, shift
    invariance and ``eig`` (:func:`automodal.core.bootstrap.replicates_from_schur`). Both
    run in ``jobs`` threads. The result does not depend on ``jobs``: chunks are fixed by
    the problem size, each is computed with one BLAS thread, and results are combined in
    chunk order.
    """
    B = weights.shape[0]
    ny = H.shape[1]
    m = basis.q * ny
    n_jobs = replicate_workers(jobs, basis, H, n, B)

    def work(r: range) -> list[bootstrap.ReplicateModes]:
        S = subspace.schur_complement(sums, slice(r.start, r.stop))
        return bootstrap.replicates_from_schur(
            S, n, basis, T, ny,
            qr_fallback=lambda i: subspace.projected_output_qr(basis, H, weights[r.start + i]),
        )

    chunks = replicate_chunks(B, m, n)
    with _workers(n_jobs) as pmap:
        sums = subspace.gram_sums(basis, H, weights, map_fn=pmap)
        return _collect(pmap(work, chunks), chunks, progress)


PARALLEL_MIN_FLOPS = 2e7
"""Below this estimated work the replicates run in the calling thread (a thread pool
costs about 0.1 ms; worker threads pay from a few milliseconds of work)."""


def replicate_workers(
    jobs: int | None, basis: subspace.RowBasis, H: np.ndarray, n: int, n_replicates: int
) -> int:
    """Worker threads :func:`run_replicates` uses: ``jobs`` if given, else all cores when
    the Gram product and the replicates' eigenproblems pay for them."""
    N, ny, nu = H.shape
    m = basis.q * ny
    gram = 4.0 * n_replicates * N * m * (ny + nu)
    return _n_jobs(jobs, n_replicates, _replicate_flops(m, n) * n_replicates + gram)


def _replicate_flops(m: int, n: int) -> float:
    """Rough floating-point work of one replicate: eigh of ``m x m``, eig of ``n x n``."""
    return 9.0 * m**3 + 25.0 * n**3


def band_records(
    data: FRFData, freq: np.ndarray, reciprocal: bool, resample: str
) -> np.ndarray | None:
    """The repeated records over the analysed lines (oriented like the analysed FRF), or
    ``None`` when the replicates resample frequency lines."""
    if resample not in ("auto", "lines", "records"):
        raise ValueError(f"unknown resample {resample!r}")
    rec = data.records
    usable = rec is not None and rec.shape[0] >= 2
    if resample == "records" and not usable:
        raise InputError("resampling records needs at least two records (/records/frf)",
                         data.source)
    if resample == "lines" or not usable:
        return None
    rec = rec[:, np.isin(data.frequency, freq)]
    return np.ascontiguousarray(rec.transpose(0, 1, 3, 2)) if reciprocal else rec


def run_record_replicates(
    basis: subspace.RowBasis,
    records: np.ndarray,
    n: int,
    T: float,
    weights: np.ndarray,
    line_weights: np.ndarray,
    jobs: int | None,
    progress: Callable[[int], None] | None = None,
) -> list[bootstrap.ReplicateModes]:
    """Replicates that each average a resample of the repeated records.

    The Gram sums are not linear in the FRF, so each replicate forms its own Schur
    complement; the rest is stacked as in :func:`run_replicates`, and likewise the result
    does not depend on ``jobs``.
    """
    B = weights.shape[0]
    ny = records.shape[2]
    m = basis.q * ny
    n_jobs = _n_jobs(jobs, B, _replicate_flops(m, n) * B)

    def average(b: int) -> np.ndarray:
        return np.einsum("r,rkij->kij", weights[b] / weights[b].sum(), records)

    def work(r: range) -> list[bootstrap.ReplicateModes]:
        Hb = [average(b) for b in r]
        S = np.stack([subspace.single_schur(basis, h, line_weights) for h in Hb])
        return bootstrap.replicates_from_schur(
            S, n, basis, T, ny,
            qr_fallback=lambda i: subspace.projected_output_qr(basis, Hb[i], line_weights),
        )

    chunks = replicate_chunks(B, m, n)
    with _workers(n_jobs) as pmap:
        return _collect(pmap(work, chunks), chunks, progress)


def _n_jobs(jobs: int | None, n_tasks: int, flops: float = np.inf) -> int:
    """Worker threads to use: ``jobs`` if given, else all cores when the work pays for them."""
    import os

    if jobs is None or jobs <= 0:
        jobs = (os.cpu_count() or 1) if flops >= PARALLEL_MIN_FLOPS else 1
    return max(1, min(int(jobs), n_tasks))


def _percentiles(x: np.ndarray) -> tuple[float, float]:
    lo, hi = np.percentile(x, [2.5, 97.5])
    return float(lo), float(hi)


def _std(x: np.ndarray) -> float:
    return float(np.std(x, ddof=1)) if x.size > 1 else 0.0


def _shape_spread(rep: np.ndarray, members: np.ndarray) -> np.ndarray:
    """Per-channel spread of member shapes aligned (complex scale) to the representative."""
    if members.shape[1] < 2:
        return np.zeros(rep.size)
    alpha = (members.conj().T @ rep) / np.sum(np.abs(members) ** 2, axis=0)
    aligned = members * alpha[None, :]
    return np.sqrt(np.mean(np.abs(aligned - aligned.mean(axis=1, keepdims=True)) ** 2, axis=1))


# ---------------------------------------------------------------------------------------
# The whole run
# ---------------------------------------------------------------------------------------


@dataclass
class Prepared:
    """The analysed data, ready for identification (see :func:`prepare`)."""

    data: FRFData  # after the checks (channels or lines may have been dropped)
    frequency: np.ndarray  # analysed lines, Hz
    H: np.ndarray  # analysed FRF, oriented for identification (reciprocity applied)
    band_hz: tuple[float, float]
    reciprocal: bool
    omega: np.ndarray
    T: float  # bilinear scale
    z: np.ndarray  # lines on the unit circle
    scales: np.ndarray  # per-output RMS scaling
    Hs: np.ndarray  # scaled FRF
    line_weights: np.ndarray


def prepare(data: FRFData, s: Settings, warnings: list[str]) -> Prepared:
    """Band, data checks, reciprocity, bilinear map, channel scaling and line weights.

    The first steps of :func:`identify`, also used by the benchmarks so that they time
    exactly what the pipeline runs. Warnings are appended to ``warnings``.
    """
    freq, H, band = select_band(data, s.band_hz, warnings)
    data, freq, H = checks.prepare(data, freq, H, warnings)
    H, reciprocal = apply_reciprocity(H, warnings)
    omega = 2.0 * np.pi * freq
    T = default_scale(omega[0], omega[-1])
    scales = subspace.channel_scales(H)
    Hs = H / scales[None, :, None]
    return Prepared(
        data=data, frequency=freq, H=H, band_hz=band, reciprocal=reciprocal, omega=omega, T=T,
        z=to_unit_circle(omega, T), scales=scales, Hs=Hs,
        line_weights=subspace.envelope_weights(Hs),
    )


def identify(
    data: FRFData,
    settings: Settings | None = None,
    progress: Callable[[int], None] | None = None,
) -> Result:
    """Identify the modes of a test, with no human choice.

    Parameters
    ----------
    data : FRFData
        The test.
    settings : Settings, optional
        Overrides of the automatic choices.
    progress : callable, optional
        Called with the number of replicates finished since the last call.

    Returns
    -------
    Result
    """
    data = as_frfdata(data)
    from threadpoolctl import threadpool_limits

    # One BLAS thread for the many small dense problems (measured: 0.75 s against 0.9 s
    # end to end on a 6-DOF chain, and far steadier on a busy machine); the replicates
    # share the cores through worker threads (run_replicates).
    with threadpool_limits(1):
        return _identify(data, settings or Settings(), progress)


def _identify(
    data: FRFData, s: Settings, progress: Callable[[int], None] | None
) -> Result:
    """:func:`identify` with BLAS limited by the caller."""
    t0 = time.perf_counter()
    warnings: list[str] = []
    p = prepare(data, s, warnings)
    data, freq, H, band, reciprocal = p.data, p.frequency, p.H, p.band_hz, p.reciprocal
    omega, T, z, scales, Hs, lw = p.omega, p.T, p.z, p.scales, p.Hs, p.line_weights
    N, ny, nu = H.shape

    # -- orders ---------------------------------------------------------------------
    n_limit = order_limit(N, ny, nu)
    if s.max_order is not None:
        need = _lines_needed(int(s.max_order), ny, nu)
        if N < need:
            raise InputError(
                f"{N} frequency lines in the band are too few for model order {s.max_order}:"
                f" the identification needs at least {need}",
                data.source,
            )
        n_limit = min(n_limit, int(s.max_order) - int(s.max_order) % 2)
    if n_limit < 4:
        raise InputError(
            f"{N} frequency lines in the band are too few: the identification needs at least"
            f" {_lines_needed(4, ny, nu)}",
            data.source,
        )
    orders, misfit = scan(z, Hs, lw, min(n_limit, MAX_SCAN_ORDER), count_peaks(Hs))
    n0 = order.order_at_floor(orders, misfit)
    cap = n_limit if s.max_order is not None else min(n_limit, MAX_REFERENCE_ORDER)
    n_hi = order.excessive_order(n0, cap)

    # -- reference model ------------------------------------------------------------
    q = subspace.block_rows(n_hi, ny)
    basis = subspace.row_basis(z, q)
    O, sv, _ = subspace.observability(basis, Hs, n_hi, weights=lw)
    A, Cs = subspace.shift_invariance(O, ny, basis)
    Bd, Ds = subspace.estimate_bd(z, Hs, A, Cs, weights=lw)
    ref_model = subspace.StateSpaceModel(
        Ad=A, Bd=Bd, Cd=Cs * scales[:, None], Dd=Ds * scales[:, None], T=T, q=q,
        singular_values=sv,
    )
    ref = modes_of_discrete(A, Cs, T, Bd)
    decay = float(data.attributes.get("window_decay_per_s", 0.0) or 0.0)
    ref.poles = ref.poles + decay  # an exponential window moved every pole by -decay
    contribution = modal_contribution(ref, A, Bd, Cs, Ds)
    band_w = (float(omega[0]), float(omega[-1]))
    cand = clustering.physical_candidates(ref.poles, band_w, s.zeta_max)
    o_ref = moc_vectors(ref.shapes, ref.mu, q)
    o_real = _real_mode_vectors(A, Cs, q)
    cand_idx = np.flatnonzero(cand)
    groups_local = clustering.coalescent_groups(ref.poles[cand_idx], s.coalescence)
    groups = clustering.split_weak_members(
        [cand_idx[g] for g in groups_local], contribution
    )

    # -- bootstrap ------------------------------------------------------------------
    rng = np.random.default_rng(s.seed)
    records = band_records(data, freq, reciprocal, s.resample)
    if records is not None:
        rw = bootstrap.record_weights(records.shape[0], s.n_bootstrap, rng)
        reps = run_record_replicates(
            basis, records / scales[None, None, :, None], n_hi, T, rw, lw, s.jobs, progress
        )
        warnings.append(
            f"bootstrap over the {records.shape[0]} repeated records (each replicate averages"
            " a resample of them): the spread reflects the records' own noise"
        )
    else:
        weights = bootstrap.line_weights(N, s.n_bootstrap, rng) * lw[None, :]
        reps = run_replicates(basis, Hs, n_hi, T, weights, s.jobs, progress)
        warnings.append(
            "bootstrap over frequency lines: the spread is conditional on the one noise"
            " realization in the data"
        )
    n_qr = sum(r.path == "qr" for r in reps)
    replicate = np.concatenate([np.full(len(r.poles), b) for b, r in enumerate(reps)]).astype(int)
    poles = np.concatenate([r.poles for r in reps]) + decay if reps else np.zeros(0, complex)
    mu = np.concatenate([r.mu for r in reps]) if reps else np.zeros(0, complex)
    shapes = np.hstack([r.shapes for r in reps]) if reps else np.zeros((ny, 0), complex)
    o = moc_vectors(shapes, mu, q)
    groups, capacity = clustering.split_stable_groups(
        groups, o_ref, o, replicate, s.n_bootstrap, contribution, ref.poles, s.threshold
    )
    refsub = clustering.reference_subspaces(o_ref, cand, o_real, groups, capacity)

    # -- clustering -----------------------------------------------------------------
    labels, rho = clustering.assign(o, replicate, refsub, s.threshold)
    labels, _ = clustering.trim(labels, o, poles, replicate, refsub.dims)

    modes = _summarise(labels, rho, poles, shapes, replicate, refsub, ref, scales, s, contribution)
    physical_ref = sorted(
        {int(i) for m in modes if m.physical for i in refsub.groups[m.cluster][: m.cluster_dim]}
    )
    H_syn = synthesize(A, Bd, Cs, Ds, z, np.array(physical_ref, dtype=int)) * scales[None, :, None]
    if reciprocal:
        H_syn, H_meas = H_syn.transpose(0, 2, 1), H.transpose(0, 2, 1)
    else:
        H_meas = H
    wn = np.abs(poles)
    table = PoleTable(
        frequency_hz=wn / (2 * np.pi),
        damping_ratio=-poles.real / np.where(wn > 0, wn, 1.0),
        cluster=labels,
        replicate=replicate,
    )
    orders_info = {
        "scanned": [int(x) for x in orders],
        "misfit": [float(x) for x in misfit],
        "n0": int(n0),
        "reference": int(n_hi),
        "block_rows": int(q),
        "basis": "monomial" if basis.monomial else "orthonormal",
        "bilinear_T": float(T),
        "replicates_on_qr_path": int(n_qr),
    }
    return Result(
        modes=modes,
        trashbox_members=int(np.sum(labels == clustering.TRASHBOX)),
        n_clusters=len(refsub.groups),
        settings=s.to_dict(),
        warnings=warnings,
        poles=table,
        band_hz=(float(band[0]), float(band[1])),
        orders=orders_info,
        runtime_s=time.perf_counter() - t0,
        reference_model=ref_model,
        reciprocity=reciprocal,
        frf_fit=(freq, np.ascontiguousarray(H_meas), np.ascontiguousarray(H_syn)),
        shape_channels=list(data.input_names if reciprocal else data.output_names),
        n_lines=int(N),
    )


def modal_contribution(
    modes: ModeSet, A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray
) -> np.ndarray:
    """How much each mode makes of the model's FRF at its own resonance, in [0, ~1].

    The mode's term ``R / (z - mu)`` (``R = C v l^T``) at the point of the unit circle
    nearest its pole, over the whole model's FRF there (Frobenius norms, scaled
    channels). A physical mode dominates its resonance (about 1); a mode that only
    fits noise contributes little.
    """
    mu = modes.mu
    if mu.size == 0 or modes.participation is None:
        return np.zeros(mu.size)
    lam, V = np.linalg.eig(A)
    idx = [int(np.argmin(np.abs(lam - m))) for m in mu]
    psi = C @ V[:, idx]
    resid = np.einsum("ai,ib->iab", psi, modes.participation)  # (m, ny, nu)
    zc = mu / np.abs(mu)
    term = np.linalg.norm(resid, axis=(1, 2)) / np.maximum(np.abs(zc - mu), 1e-300)
    total = np.linalg.norm(subspace.frequency_response(A, B, C, D, zc), axis=(1, 2))
    return term / np.maximum(total, 1e-300)


def synthesize(
    A: np.ndarray,
    B: np.ndarray,
    C: np.ndarray,
    D: np.ndarray,
    z: np.ndarray,
    keep: np.ndarray,
) -> np.ndarray:
    """FRF of a discrete-time model keeping only some oscillatory modes (and ``D``).

    ``keep`` indexes the model's modes with ``Im lambda > 0`` sorted by frequency (as in
    :func:`automodal.core.modal.modes_of_discrete`); each kept mode contributes its term and
    its conjugate's, so the result is the FRF of the physical modes alone.
    """
    mu, V = np.linalg.eig(A)
    lam = poles_d2c(mu, 1.0)  # the order by |lambda| does not depend on T
    pos = np.flatnonzero(lam.imag > 0)
    pos = pos[np.argsort(np.abs(lam[pos]))]
    H = np.broadcast_to(D, (z.size,) + D.shape).astype(complex)
    if keep.size == 0:
        return H
    sel = pos[keep]
    L = np.linalg.solve(V, B)[sel]
    CV = (C @ V)[:, sel]

    def terms(points: np.ndarray) -> np.ndarray:
        g = 1.0 / (points[:, None] - mu[None, sel])
        return np.einsum("ia,ka,aj->kij", CV, g, L, optimize=True)

    # each mode with its conjugate: R / (z - mu) + conj(R) / (z - conj mu)
    return H + terms(z) + np.conj(terms(z.conj()))


def apply_reciprocity(H: np.ndarray, warnings: list[str]) -> tuple[np.ndarray, bool]:
    """Swap inputs and outputs (``H^T``) when there are more inputs than outputs.

    A roving-hammer test (one sensor, many hit points) is, by Maxwell-Betti reciprocity, the
    same as one force and many sensors. Identification is much cheaper and better posed
    with many outputs (the block rows scale with ``n / ny``), and the mode shapes then live
    on the hit points, which is what such a test measures.
    """
    if H.shape[2] <= H.shape[1]:
        return H, False
    warnings.append(
        f"reciprocity assumed: the {H.shape[2]} inputs were treated as outputs and the"
        f" {H.shape[1]} output(s) as input(s); mode shapes are given over the inputs"
    )
    return np.ascontiguousarray(H.transpose(0, 2, 1)), True


def _lines_needed(n: int, ny: int, nu: int) -> int:
    q = subspace.block_rows(n, ny)
    return int(np.ceil(q * (nu + ny) / (2.0 * BOOTSTRAP_LINE_FRACTION * nu)))


def _real_mode_vectors(A: np.ndarray, C: np.ndarray, k: int) -> np.ndarray:
    """MOC vectors of the real (non-oscillatory) poles of a discrete-time model."""
    mu, V = np.linalg.eig(A)
    real = mu.imag == 0
    if not real.any():
        return np.zeros((k * C.shape[0], 0), dtype=complex)
    return moc_vectors(normalise_shapes(C @ V[:, real]), mu[real], k)


def _summarise(
    labels: np.ndarray,
    rho: np.ndarray,
    poles: np.ndarray,
    shapes_scaled: np.ndarray,
    replicate: np.ndarray,
    refsub: clustering.ReferenceSubspaces,
    ref: ModeSet,
    scales: np.ndarray,
    s: Settings,
    contribution: np.ndarray,
) -> list[IdentifiedMode]:
    """Features, physicalness and statistics of every surviving cluster.

    The decorrelation feature uses each member's correlation ``rho`` with the cluster's
    reference subspace, and the scatter feature the members' distance from the reference
    model's pole of the same rank: both stay meaningful for a cluster of one member.
    """
    clusters = [c for c in range(len(refsub.groups)) if np.any(labels == c)]
    feats, per_cluster = [], []
    for c in clusters:
        idx = np.flatnonzero(labels == c)
        rank = clustering.rank_within_replicate(poles[idx], replicate[idx])
        group = refsub.groups[c][: refsub.dims[c]]  # the representatives, in rank order
        centre = ref.poles[group][np.minimum(rank, group.size - 1)]
        rel = np.abs(poles[idx] - centre) / np.abs(centre)
        feats.append(
            physicalness.cluster_features(
                idx.size, s.n_bootstrap, int(refsub.dims[c]), rho[idx], rel,
                float(np.max(contribution[group])),
            )
        )
        per_cluster.append((idx, rank))
    phys = physicalness.physicalness(np.array(feats)) if feats else np.zeros(0)
    # a cluster whose members are mostly unstable is never physical (method.md, 1.7)
    for i, (idx, _) in enumerate(per_cluster):
        if np.median(poles[idx].real) >= 0:
            phys[i] = 0.0

    shapes_data = normalise_shapes(shapes_scaled * scales[:, None])
    ref_shapes = normalise_shapes(ref.shapes * scales[:, None])
    modes: list[IdentifiedMode] = []
    for c, (idx, rank), f, p in zip(clusters, per_cluster, feats, phys):
        group = refsub.groups[c][: refsub.dims[c]]
        for r in range(int(refsub.dims[c])):
            sel = idx[rank == r]
            if sel.size == 0:
                continue
            fr = np.abs(poles[sel]) / (2 * np.pi)
            zt = -poles[sel].real / np.abs(poles[sel])
            rep = ref_shapes[:, group[min(r, group.size - 1)]]
            rep_unit = unit_max_shapes(rep[:, None])[:, 0]
            members = unit_max_shapes(shapes_data[:, sel])
            modes.append(
                IdentifiedMode(
                    id=0,
                    frequency_hz=float(np.median(fr)),
                    frequency_std_hz=_std(fr),
                    frequency_ci95_hz=_percentiles(fr),
                    damping_ratio=float(np.median(zt)),
                    damping_std=_std(zt),
                    damping_ci95=_percentiles(zt),
                    physicalness=float(p),
                    physical=bool(p >= s.min_physicalness),
                    n_members=int(sel.size),
                    mode_shape=rep_unit,
                    mode_shape_std=_shape_spread(rep_unit, members),
                    mpc=float(mpc(rep_unit)[0]),
                    cluster=int(c),
                    cluster_dim=int(refsub.dims[c]),
                    features=dict(zip(physicalness.FEATURE_NAMES, map(float, f))),
                )
            )
    modes.sort(key=lambda m: m.frequency_hz)
    for i, m in enumerate(modes, start=1):
        m.id = i
    return modes
