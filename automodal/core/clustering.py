"""Clustering of bootstrap modes: reference groups, one-pass assignment with a Trashbox,
and trimming (``method.md`` sections 2-4).

Labels: a bootstrap mode carries the index of its cluster, or :data:`TRASHBOX` (``-1``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from automodal.core.correlation import (
    orthonormal_basis,
    subspace_correlation,
    subspace_correlations,
)

TRASHBOX = -1
MAD_SCALE = 1.4826  # MAD of a normal sample -> its standard deviation


# ---------------------------------------------------------------------------------------
# Reference groups
# ---------------------------------------------------------------------------------------


def physical_candidates(
    poles: np.ndarray, band_rad_s: tuple[float, float], zeta_max: float = 0.2
) -> np.ndarray:
    """Mask of reference modes that may be physical: stable, ``0 < zeta < zeta_max``, in band.

    Parameters
    ----------
    poles : ndarray
        Continuous-time poles (rad/s), ``Im > 0`` for oscillatory modes.
    band_rad_s : (float, float)
        Analysed band in rad/s.
    zeta_max : float
        Largest damping ratio of a candidate.
    """
    poles = np.asarray(poles)
    wn = np.abs(poles)
    zeta = -poles.real / np.where(wn > 0, wn, 1.0)
    return (
        (poles.imag > 0)
        & (poles.real < 0)
        & (zeta > 0)
        & (zeta < zeta_max)
        & (wn >= band_rad_s[0])
        & (wn <= band_rad_s[1])
    )


def coalescent_groups(
    poles: np.ndarray, alpha: float = 1.0, resolution: float = 0.0
) -> list[np.ndarray]:
    """Group poles closer than ``alpha`` half-power bandwidths, or than the frequency
    resolution of the data (union of pairs).

    Poles ``i`` and ``j`` join when ``|l_i - l_j| < alpha * min(-Re l_i, -Re l_j)``: each
    lies within the other's half-power bandwidth. (With ``max`` a heavily damped noise
    pole near a physical one swept it into a pair.) Poles closer than ``resolution``
    (rad/s, the line spacing) cannot be told apart by the data either and join too; the
    bootstrap then decides what each group is (:func:`split_stable_groups`).

    Returns
    -------
    list of ndarray
        Index arrays into ``poles``, each sorted, groups ordered by their first pole's
        natural frequency.
    """
    poles = np.asarray(poles)
    m = poles.size
    parent = np.arange(m)

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    dist = np.abs(poles[:, None] - poles[None, :])
    width = np.maximum(
        alpha * np.minimum(-poles.real[:, None], -poles.real[None, :]), resolution
    )
    for i, j in zip(*np.nonzero(np.triu(dist < width, k=1))):
        ri, rj = root(int(i)), root(int(j))
        if ri != rj:
            parent[max(ri, rj)] = min(ri, rj)
    roots = np.array([root(i) for i in range(m)], dtype=int)
    groups = [np.flatnonzero(roots == r) for r in np.unique(roots)]
    return sorted(groups, key=lambda g: float(np.min(np.abs(poles[g]))))


def split_weak_members(
    groups: list[np.ndarray], contribution: np.ndarray, ratio: float = 0.25
) -> list[np.ndarray]:
    """Take out of each group the members much weaker than its strongest one.

    A member whose modal contribution is below ``ratio`` times the group's largest stays
    a singleton: the companions that an over-sized model puts next to a physical pole
    contributed 0.05-0.18 beside the physical pole's 0.95 (simulated chain, 5 % noise).
    """
    out: list[np.ndarray] = []
    for g in groups:
        strong = contribution[g] >= ratio * np.max(contribution[g])
        if strong.all():
            out.append(g)
            continue
        out.append(g[strong])
        out.extend(np.array([i]) for i in g[~strong])
    return out


def split_stable_groups(
    groups: list[np.ndarray],
    o_ref: np.ndarray,
    o_boot: np.ndarray,
    replicate: np.ndarray,
    n_bootstrap: int,
    strength: np.ndarray,
    poles: np.ndarray,
    threshold: float = 0.8,
    min_union_only: float = 0.25,
    min_full: float = 0.5,
) -> tuple[list[np.ndarray], list[int]]:
    """Decide, from the bootstrap, what a group of close reference poles is.

    * **A repeated root** (kept, one cluster that takes ``d`` modes per replicate): at least
      ``min_full`` of the replicates give ``d`` or more modes that correlate with the
      group's span (``rho >= threshold``), and at least ``min_union_only`` of those modes
      correlate with the span but with none of the single vectors (the eigenvectors of a
      repeated root wander between replicates; the span does not).
    * **Distinct modes** (split into singletons): the replicates give ``d`` modes, each
      close to one single vector.
    * **One mode described by several poles** (one cluster that takes one mode per
      replicate, represented by the strongest pole): the replicates mostly give fewer
      than ``d`` modes. Measured: the pole-distance rule alone paired physical modes with
      over-fitting companion poles, which halved the mode's occurrence (simulated chains)
      or split one mode into two physical clusters (LADISK beam, 958.53 and 958.57 Hz).

    Parameters
    ----------
    groups : list of ndarray
        Indices into the columns of ``o_ref``.
    o_ref : ndarray, shape (dim, m)
        Unit-norm MOC vectors of the reference modes.
    o_boot : ndarray, shape (dim, M)
        Unit-norm MOC vectors of all bootstrap modes.
    replicate : ndarray of int, shape (M,)
        Replicate of each bootstrap mode.
    n_bootstrap : int
        Number of replicates.
    strength : ndarray, shape (m,)
        Modal contribution of each reference mode (chooses the representative).
    poles : ndarray, shape (m,)
        Reference poles (orders the members of a repeated root).
    threshold : float
        ``tau_1``.
    min_union_only, min_full : float
        The two fractions above.

    Returns
    -------
    groups : list of ndarray
        Each group's reference modes; its first ``capacity`` entries represent it.
    capacity : list of int
        Modes each replicate may give to the group.
    """
    out: list[np.ndarray] = []
    capacity: list[int] = []
    # every group's union and best single correlations from two products over all the
    # modes, in the order of the groups of two or more
    several = [g for g in groups if g.size >= 2]
    unions = iter(subspace_correlations([orthonormal_basis(o_ref[:, g]) for g in several],
                                        o_boot))
    singles = iter(np.maximum.reduceat(
        np.abs(o_ref[:, np.concatenate(several)].conj().T @ o_boot) ** 2,
        np.cumsum([0] + [g.size for g in several[:-1]]), axis=0) if several else ())
    for g in groups:
        if g.size < 2:
            out.append(g)
            capacity.append(1)
            continue
        rho_union, rho_single = next(unions), next(singles)
        near = rho_union >= threshold
        per_rep = np.bincount(replicate[near], minlength=n_bootstrap)
        full = np.count_nonzero(per_rep >= g.size) >= min_full * n_bootstrap
        union_only = np.count_nonzero(near & (rho_single < threshold))
        if full and union_only >= min_union_only * np.count_nonzero(near):
            out.append(g[np.argsort(np.abs(poles[g]))])
            capacity.append(int(g.size))
        elif full:
            out.extend(np.array([i]) for i in g)
            capacity.extend([1] * int(g.size))
        else:
            out.append(g[np.argsort(-strength[g])])
            capacity.append(1)
    return out, capacity


@dataclass
class ReferenceSubspaces:
    """The cluster subspaces and the noise subspace built from the reference model.

    Attributes
    ----------
    groups : list of ndarray
        Reference-mode indices of each cluster (into the reference :class:`ModeSet`); the
        first ``capacity`` entries represent the cluster.
    bases : list of ndarray
        Orthonormal basis of each cluster's MOC vectors.
    noise_basis : ndarray
        Orthonormal basis of the noise modes' MOC vectors.
    capacity : list of int
        Modes a replicate may give to each cluster (its dimension as a mode set).
    """

    groups: list[np.ndarray]
    bases: list[np.ndarray]
    noise_basis: np.ndarray
    capacity: list[int]

    @property
    def dims(self) -> np.ndarray:
        """Modes per replicate of each cluster (2 for a repeated pair)."""
        return np.array(self.capacity, dtype=int)


def reference_subspaces(
    o_ref: np.ndarray,
    candidate: np.ndarray,
    o_noise_extra: np.ndarray,
    groups: list[np.ndarray],
    capacity: list[int] | None = None,
) -> ReferenceSubspaces:
    """Cluster and noise subspaces.

    The noise subspace is what the noise modes span *beyond* the clusters' spans: their MOC
    vectors with the clusters' directions projected out. An over-sized model fitted to very
    clean data puts noise poles beside lightly damped modes (some just unstable or too
    damped to be candidates). For one output a MOC vector is a function of the pole alone,
    and poles a few Hz apart correlate at 0.9-0.99, so those noise modes, alone or together,
    spanned the mode's own direction: ``rho_noise`` equalled ``rho`` for every replicate's
    copy of the mode, which went to the Trashbox (LADISK hammer hits: the 3669, 4128, 4164
    and 4392 Hz peaks, the strongest of the test, kept 2-37 of 100 replicates). A noise mode
    still correlates with what is left, so the Trashbox keeps its part.

    Parameters
    ----------
    o_ref : ndarray, shape (dim, m)
        MOC vectors of the reference model's oscillatory modes.
    candidate : ndarray of bool, shape (m,)
        Physical candidates; the others span the noise subspace.
    o_noise_extra : ndarray, shape (dim, r)
        MOC vectors of the reference model's real poles (noise too).
    groups : list of ndarray
        Coalescent groups, as indices into the candidates' positions in ``o_ref``.
    capacity : list of int, optional
        Modes per replicate of each group (default: its number of members).
    """
    bases = [orthonormal_basis(o_ref[:, g]) for g in groups]
    noise = np.hstack([o_ref[:, ~candidate], o_noise_extra])
    if bases and noise.shape[1]:
        span = orthonormal_basis(np.hstack(bases))
        noise = noise - span @ (span.conj().T @ noise)
    cap = [int(g.size) for g in groups] if capacity is None else list(capacity)
    return ReferenceSubspaces(
        groups=groups, bases=bases, noise_basis=orthonormal_basis(noise), capacity=cap
    )


# ---------------------------------------------------------------------------------------
# One-pass assignment
# ---------------------------------------------------------------------------------------


def assign(
    o: np.ndarray,
    replicate: np.ndarray,
    ref: ReferenceSubspaces,
    threshold: float = 0.8,
) -> tuple[np.ndarray, np.ndarray]:
    """Assign bootstrap modes to clusters or to the Trashbox, in one pass.

    A mode goes to the cluster ``c`` with the highest ``rho_c`` if ``rho_c >= threshold``
    and ``rho_c > rho_noise``; a replicate gives at most ``dim(S_c)`` modes to cluster
    ``c`` (the best-correlated), the surplus goes to the Trashbox.

    Parameters
    ----------
    o : ndarray, shape (dim, M)
        Unit-norm MOC vectors of all bootstrap modes.
    replicate : ndarray of int, shape (M,)
        Which replicate each mode comes from.
    ref : ReferenceSubspaces
    threshold : float
        ``tau_1``.

    Returns
    -------
    labels : ndarray of int, shape (M,)
        Cluster index or :data:`TRASHBOX`.
    rho : ndarray, shape (M,)
        Correlation with the chosen (or best) cluster.
    """
    M = o.shape[1]
    if not ref.bases or M == 0:
        return np.full(M, TRASHBOX, dtype=int), np.zeros(M)
    rho_all = subspace_correlations([*ref.bases, ref.noise_basis], o)  # (n_clusters + 1, M)
    rho_all, rho_noise = rho_all[:-1], rho_all[-1]
    best = np.argmax(rho_all, axis=0)
    rho = rho_all[best, np.arange(M)]
    labels = np.where((rho >= threshold) & (rho > rho_noise), best, TRASHBOX)
    dims = ref.dims
    # capacity: per (replicate, cluster) keep the dims[c] best
    order = np.lexsort((-rho, labels, replicate))
    prev_key = None
    count = 0
    for i in order:
        if labels[i] == TRASHBOX:
            continue
        key = (replicate[i], labels[i])
        count = count + 1 if key == prev_key else 1
        prev_key = key
        if count > dims[labels[i]]:
            labels[i] = TRASHBOX
    return labels, rho


# ---------------------------------------------------------------------------------------
# Trimming
# ---------------------------------------------------------------------------------------


def _robust_upper(x: np.ndarray, k: float) -> float:
    med = np.median(x)
    return float(med + k * MAD_SCALE * np.median(np.abs(x - med)))


def principal_correlation(o_members: np.ndarray, dim: int) -> np.ndarray:
    """``r^2 = ||U^H o_j||^2`` of each member with the members' principal ``dim``-subspace.

    ``U`` holds the ``dim`` leading left singular vectors of the members ``o`` (``d x m``).
    They come from the smaller of the two Gram matrices: the leading eigenvectors of
    ``o o^H`` when ``d < m``; otherwise ``o^H o = V S^2 V^H`` gives
    ``r_j^2 = sum_k s_k^2 |V_jk|^2`` over the leading ``k``. The leading directions are
    well conditioned in either (the members correlate with them), and ``r^2`` agrees with
    the SVD's to 1e-14; one cluster of 100 members of 222 or 592 numbers took 2.6-3.9 ms
    instead of 6.6-12 ms, and the trimming computes it for every cluster, twice. Where the
    ``dim``-th and the next singular values nearly tie, the subspace itself is ill-defined
    and both ways of computing it differ by about ``1e-16 / gap``.
    """
    o = np.asarray(o_members)
    d, m = o.shape
    if d < m:
        _, U = np.linalg.eigh(o @ o.conj().T)
        return subspace_correlation(U[:, ::-1][:, :dim], o)
    w, V = np.linalg.eigh(o.conj().T @ o)
    return np.abs(V[:, ::-1][:, :dim]) ** 2 @ np.clip(w[::-1][:dim], 0.0, None)


def rank_within_replicate(poles: np.ndarray, replicate: np.ndarray) -> np.ndarray:
    """Rank of each member's natural frequency among the members of the same replicate.

    For a cluster of dimension ``d`` (near-repeated modes) rank ``r`` picks out the
    ``r``-th lowest of the ``d`` modes; for ``d = 1`` every rank is 0.
    """
    rank = np.zeros(poles.size, dtype=int)
    order = np.lexsort((np.abs(poles), replicate))
    prev = None
    r = 0
    for i in order:
        r = r + 1 if replicate[i] == prev else 0
        prev = replicate[i]
        rank[i] = r
    return rank


def pole_deviation(poles: np.ndarray, rank: np.ndarray) -> np.ndarray:
    """``|l_j - median|`` with the component-wise median of the members of the same rank."""
    dev = np.zeros(poles.size)
    for r in np.unique(rank):
        sel = rank == r
        med = np.median(poles[sel].real) + 1j * np.median(poles[sel].imag)
        dev[sel] = np.abs(poles[sel] - med)
    return dev


def trim(
    labels: np.ndarray,
    o: np.ndarray,
    poles: np.ndarray,
    replicate: np.ndarray,
    dims: np.ndarray,
    k_corr: float = 3.0,
    k_pole: float = 5.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Second correlation pass: send stray members of each cluster to the Trashbox.

    A member leaves its cluster when its correlation with the cluster's principal
    subspace is a robust low outlier (below ``median - k_corr * MAD``) or its pole is a
    robust far outlier (beyond ``median + k_pole * MAD`` of the pole deviations).

    Returns
    -------
    labels : ndarray of int
        Updated labels.
    r2 : ndarray
        Each mode's correlation with its cluster's principal subspace (0 in the Trashbox).
    """
    labels = labels.copy()
    r2 = np.zeros(labels.size)
    for c in np.unique(labels[labels != TRASHBOX]):
        idx = np.flatnonzero(labels == c)
        if idx.size < 3:
            r2[idx] = principal_correlation(o[:, idx], int(dims[c]))
            continue
        r = principal_correlation(o[:, idx], int(dims[c]))
        dev = pole_deviation(poles[idx], rank_within_replicate(poles[idx], replicate[idx]))
        med_r = np.median(r)
        low = min(med_r - k_corr * MAD_SCALE * np.median(np.abs(r - med_r)), 1.0 - 1e-9)
        # floors keep rounding-level spreads (noise-free data) from trimming anything
        far = max(_robust_upper(dev, k_pole), 1e-9 * float(np.median(np.abs(poles[idx]))))
        out = (r < low) | (dev > far)
        labels[idx[out]] = TRASHBOX
        keep = idx[~out]
        if keep.size:
            r2[keep] = principal_correlation(o[:, keep], int(dims[c]))
    return labels, r2
