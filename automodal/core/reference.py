"""The reference model of the excessive order, and the clustering of the bootstrap
poles against it (``method.md`` sections 2-4).

:func:`build_reference` identifies the reference model (with
:func:`automodal.core.subspace.identify_scaled`, the function behind
:func:`~automodal.core.subspace.identify`), decomposes it once
(:class:`~automodal.core.modal_model.ModalModel`) and derives its modes, their modal
contributions, the physical candidates and their coalescent groups.
:func:`cluster_against_reference` then settles each group from the bootstrap, builds
the reference subspaces, assigns every bootstrap pole (one pass, Trashbox) and trims.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from automodal.core import clustering, subspace
from automodal.core.correlation import moc_vectors
from automodal.core.modal import ModeSet
from automodal.core.modal_model import ModalModel
from automodal.core.pole_map import PoleMap
from automodal.core.replicates import ReplicatePoles


@dataclass
class Reference:
    """The reference model and what clustering needs of it.

    Attributes
    ----------
    model : StateSpaceModel
        The model in the data's units; ``model.path`` says whether the Gram or the QR
        path gave its subspace.
    modal : ModalModel
        Its modal form in scaled units (the one eigendecomposition of ``A``).
    basis : RowBasis
        Row basis of its block rows (shared by the replicates).
    modes : ModeSet
        Its oscillatory modes (scaled shapes; the structure's poles, see
        :class:`~automodal.core.pole_map.PoleMap`).
    contribution : ndarray
        Modal contribution of each mode (:meth:`ModalModel.contributions`).
    candidates : ndarray of bool
        Physical candidates (:func:`automodal.core.clustering.physical_candidates`).
    moc : ndarray
        MOC vectors of the modes (``q`` block rows).
    moc_real : ndarray
        MOC vectors of the real poles.
    groups : list of ndarray
        Coalescent groups of candidates, weak members split off.
    """

    model: subspace.StateSpaceModel
    modal: ModalModel
    basis: subspace.RowBasis
    modes: ModeSet
    contribution: np.ndarray
    candidates: np.ndarray
    moc: np.ndarray
    moc_real: np.ndarray
    groups: list[np.ndarray]

    @property
    def q(self) -> int:
        """Block rows."""
        return self.basis.q


def build_reference(
    z: np.ndarray,
    Hs: np.ndarray,
    scales: np.ndarray,
    weights: np.ndarray,
    n: int,
    T: float,
    band_rad_s: tuple[float, float],
    zeta_max: float,
    coalescence: float,
    pole_map: PoleMap | None = None,
    q: int | None = None,
) -> Reference:
    """Identify the reference model of order ``n`` and prepare its groups.

    Parameters
    ----------
    z : ndarray, shape (N,)
        Lines on the unit circle.
    Hs : ndarray, shape (N, ny, nu)
        Channel-scaled FRF.
    scales : ndarray, shape (ny,)
        The channel scales (the model is reported in the data's units).
    weights : ndarray, shape (N,)
        Line weights.
    n : int
        Reference order.
    T : float
        Bilinear scale.
    band_rad_s : (float, float)
        Analysed band (rad/s), for the physical candidates.
    zeta_max : float
        Largest damping ratio of a candidate.
    coalescence : float
        Half-power bandwidths within which candidates group.
    pole_map : PoleMap, optional
        From the model's poles to the structure's (window decay, sampled spectra).
    q : int, optional
        Block rows (default :func:`automodal.core.subspace.block_rows` of ``n``).
    """
    q = subspace.block_rows(n, Hs.shape[1]) if q is None else int(q)
    basis = subspace.row_basis(z, q)
    scaled = subspace.identify_scaled(z, Hs, n, T, basis, weights=weights)
    modal = ModalModel.from_state_space(scaled)
    modes = modal.modes(pole_map)
    contribution = modal.contributions()
    cand = clustering.physical_candidates(modes.poles, band_rad_s, zeta_max)
    cand_idx = np.flatnonzero(cand)
    local = clustering.coalescent_groups(modes.poles[cand_idx], coalescence)
    groups = clustering.split_weak_members([cand_idx[g] for g in local], contribution)
    return Reference(
        model=scaled.rescaled(scales), modal=modal, basis=basis, modes=modes,
        contribution=contribution, candidates=cand, moc=moc_vectors(modes.shapes, modes.mu,
                                                                     basis.q),
        moc_real=modal.real_mode_vectors(basis.q), groups=groups,
    )


GROWING_SHARE_LIMIT = 0.5
""":func:`growing_share` above which the FRF may use the other sign convention: most of the
response the model detects in the band comes from poles that grow in time, where a
structure's modes decay (a majority, not a tuned value). Measured (session 28): at most
0.025 on 73 family and sample files (seeds 481, 533, 547), 0.997 on the sample's FRF
conjugated; but 1 on about one white-noise SISO FRF in three, which the pipeline's second
test (the conjugate fitting better) then passes."""


def growing_share(
    poles: np.ndarray, weight: np.ndarray, band_rad_s: tuple[float, float]
) -> float:
    """Share of ``weight`` (such as the detected modes' contributions) of the in-band
    modes carried by growing (unstable) poles.

    An FRF stored with the ``e^{-i omega t}`` convention is the complex conjugate of
    automodal's: each resonance ``R / (i omega - lambda)`` becomes
    ``conj(R) / (i omega + conj(lambda))``, whose pole ``-conj(lambda)`` has the same
    frequency and the opposite real part. A model of such data fits every resonance with a
    growing pole.

    Parameters
    ----------
    poles : ndarray, shape (m,)
        A model's oscillatory poles (continuous time, rad/s).
    weight : ndarray, shape (m,)
        What each mode counts for (>= 0; 0 for a mode that does not count).
    band_rad_s : (float, float)
        The analysed band in rad/s.

    Returns
    -------
    float
        In [0, 1]; 0 when no in-band mode has weight.
    """
    poles = np.asarray(poles)
    wn = np.abs(poles)
    inside = (wn >= band_rad_s[0]) & (wn <= band_rad_s[1])
    w = np.where(inside, np.asarray(weight, dtype=float), 0.0)
    total = float(np.sum(w))
    if not total > 0:
        return 0.0
    return float(np.sum(w[poles.real > 0]) / total)


@dataclass
class Clusters:
    """Bootstrap poles assigned to clusters.

    Attributes
    ----------
    labels : ndarray of int
        Cluster of each pole, :data:`automodal.core.clustering.TRASHBOX` for none.
    rho : ndarray
        Each pole's correlation with its best subspace.
    subspaces : ReferenceSubspaces
        The clusters' reference groups, bases and dimensions.
    """

    labels: np.ndarray
    rho: np.ndarray
    subspaces: clustering.ReferenceSubspaces


def cluster_against_reference(
    ref: Reference, reps: ReplicatePoles, n_bootstrap: int, threshold: float
) -> Clusters:
    """Settle the groups from the bootstrap, assign every pole in one pass and trim.

    Parameters
    ----------
    ref : Reference
        The reference model.
    reps : ReplicatePoles
        All replicates' modes.
    n_bootstrap : int
        Replicates.
    threshold : float
        ``tau_1``, the correlation a mode needs to join a cluster.
    """
    o = moc_vectors(reps.shapes, reps.mu, ref.q)
    groups, capacity = clustering.split_stable_groups(
        ref.groups, ref.moc, o, reps.replicate, n_bootstrap, ref.contribution,
        ref.modes.poles, threshold,
    )
    refsub = clustering.reference_subspaces(ref.moc, ref.candidates, ref.moc_real, groups,
                                            capacity)
    labels, rho = clustering.assign(o, reps.replicate, refsub, threshold)
    labels, _ = clustering.trim(labels, o, reps.poles, reps.replicate, refsub.dims)
    return Clusters(labels=labels, rho=rho, subspaces=refsub)
