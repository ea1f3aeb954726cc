"""Physicalness of clusters: log-scale features and anchored fuzzy c-means.

Features of a cluster: the three of ``method.md`` section 5,

1. occurrence ratio ``members / (B dim)``, in [0, 1];
2. ``log10(1 - mean rho)``, decorrelation of the members from the cluster subspace;
3. ``log10(median |l - l_ref| / |l_ref|)``, relative scatter of the members' poles;

and a fourth,

4. ``log10(modal contribution)``: how much of the reference model's FRF at the mode's
   own resonance the mode's term makes (about 1 for a physical mode).

Why a fourth: with a frequency-line bootstrap every replicate re-fits the same noise
realisation, so over-fitting modes recur (occurrence up to 0.97) with correlations and
scatters that overlap those of physical modes at 5 % noise. Measured over 18 simulated
tests (6 cases x 3 seeds, 100 replicates), clusters called physical that are not true
modes fell from 5 to 1 and missed true modes from 4 to 0 when the fourth feature was
added; the contribution's median was 0.99 for true modes and 0.005 for noise clusters.

Plain two-class fuzzy c-means always splits its data in two, so on a file without
structure half the clusters would come out "physical". Here the classes are **anchored**:
the features are standardised with fixed scales (not per-file statistics), and the data
are clustered together with copies of two fixed prototypes, one for a physical mode and
one for a noise mode, that carry as much weight as the data. The centres can move
towards the data's own groups, but the physical centre cannot wander into a cloud of
noise clusters, so a file of pure noise gives no physical cluster. The class whose centre
is nearer the physical prototype is the physical one, and physicalness is the membership
of that class.

With a noise model (issue 13) the fourth feature is the reference mode's SNR against the
noise (:func:`snr_feature`), which means the same on every file: about what fitting noise
gives a spurious mode for noise, far above it for a mode of the data. Whatever the
features, a cluster of one member or found by a minority of the replicates is never
physical (:func:`vetoed`); the refinement may still make physical a companion the data need
whose cluster a tenth of the replicates or more found, with a clear SNR, and a weak mode
whose cluster is not vetoed but scored below the line, where the likelihood holds its pole
(:func:`automodal.core.summary.refine_physical_modes`).
"""

from __future__ import annotations

import numpy as np

FEATURE_NAMES = (
    "occurrence",
    "log10_decorrelation",
    "log10_pole_scatter",
    "log10_modal_contribution",
)

PHYSICAL_PROTOTYPE = np.array([1.0, -5.0, -4.5, 0.0])
"""Features of a clearly physical cluster: found by every replicate, members correlated to
within 1e-5 of the cluster subspace, relative pole scatter 3e-5, the whole FRF at its
resonance."""

NOISE_PROTOTYPE = np.array([0.4, -1.0, -1.5, -2.3])
"""Features of a typical noise cluster: found by 40 % of the replicates, 10 % decorrelation,
3 % relative pole scatter, 0.5 % of the FRF at its frequency."""

FEATURE_SCALE = np.array([0.3, 1.5, 1.0, 0.7])
"""Fixed standardisation of the features (about the spread of each class)."""

CONTRIBUTION_RANGE = (-4.0, 0.5)

SNR_FEATURE_NAME = "log10_snr2_per_parameter"
"""Name of the fourth feature when the run has a noise model (see :func:`snr_feature`)."""

SNR_RANGE = (-2.0, 6.0)
"""Clip of :func:`snr_feature` (a reported feature; for the c-means with ``snr=True`` a
clip at about the physical prototype, 2, keeps it from outweighing the others)."""


SNR_PHYSICAL_PROTOTYPE = np.array([1.0, -5.0, -4.5, 1.5])
"""Features of a clearly physical cluster with a noise model: as
:data:`PHYSICAL_PROTOTYPE`, and an SNR^2 of 30 times what fitting noise gives a mode
(the family's "clear" threshold, SNR 30, is SNR^2 / p = 15 to 225 for p = 4 to 60)."""

SNR_NOISE_PROTOTYPE = np.array([0.4, -1.0, -1.5, 0.0])
"""Features of a noise cluster with a noise model: as :data:`NOISE_PROTOTYPE`, and the
SNR^2 that fitting noise gives a spurious mode, about its ``p`` parameters (ratio 1)."""

SNR_FEATURE_SCALE = np.array([0.3, 1.5, 1.0, 0.5])
"""Standardisation with the SNR feature (half a decade of SNR^2 per unit)."""

SPORADIC = 0.1
"""A cluster seen by fewer than this share of the replicates has its physicalness scaled
down in proportion (one member of 100 replicates: a tenth). Not the majority: a clear mode
next to a band edge was found by only a quarter of the replicates (tests/test_edge_cases.py)
and is still a mode; on the noise path :func:`vetoed` applies the majority rule."""

MAJORITY = 0.5
"""A cluster found by fewer than this share of the replicates (occurrence) is never
physical on its features: a mode of the data must be seen by most resamples of it. The
refinement's likelihood tests may still hold one found by at least :data:`SPORADIC` with a
clear SNR (a needed companion, a repeated pair's second mode, a weak mode:
:func:`automodal.core.summary.refine_physical_modes`)."""


def snr_feature(snr2: float, params: int) -> float:
    """``log10(SNR^2 / p)`` clipped to :data:`SNR_RANGE`: a mode's whitened energy over
    what fitting noise gives a spurious mode with ``p`` real parameters (about 1, i.e. 0,
    for noise; the same meaning on every file)."""
    ratio = max(float(snr2), 0.0) / max(float(params), 1.0)
    return float(np.clip(np.log10(ratio + FLOOR), *SNR_RANGE))


DETECTION_Z = 3.0
"""A mode whose SNR^2 is below ``p + DETECTION_Z sqrt(2 p)`` is not detected: fitting noise
gives a spurious mode about a chi-square with ``p`` degrees of freedom (mean ``p``, variance
``2 p``); the same quantile as the order test."""


def detection_threshold(params: int) -> float:
    """SNR^2 a mode with ``params`` real parameters needs to stand out of the noise."""
    p = float(max(params, 1))
    return p + DETECTION_Z * float(np.sqrt(2.0 * p))


def familywise_threshold(params: int, n_modes: int, alpha: float = 0.01) -> float:
    """SNR^2 that the noise gives none of ``n_modes`` spurious modes above, but with
    probability ``alpha``: the chi-square (``params`` degrees of freedom) quantile of
    ``alpha / n_modes`` (Bonferroni). For claims about a whole model, where one chance
    detection among many modes must not decide."""
    from scipy.special import chdtri

    p = float(max(params, 1))
    return float(chdtri(p, alpha / max(int(n_modes), 1)))


def vetoed(
    occurrence: float, n_members: int, snr2: float | None = None, params: int = 0
) -> bool:
    """Whether a cluster can never be physical whatever its features: one member, found
    by a minority of the replicates (occurrence below :data:`MAJORITY`), or (with a noise
    model) an SNR^2 below :func:`detection_threshold`."""
    if int(n_members) <= 1 or float(occurrence) < MAJORITY:
        return True
    return snr2 is not None and float(snr2) < detection_threshold(params)

FLOOR = 1e-12
LOG_RANGE = (-8.0, 0.0)
"""Both log features are clipped to this range: below it differences mean nothing."""


def cluster_features(
    n_members: int,
    n_bootstrap: int,
    dim: int,
    r2: np.ndarray,
    rel_scatter: np.ndarray,
    contribution: float,
) -> np.ndarray:
    """The four features of one cluster.

    Parameters
    ----------
    n_members : int
        Bootstrap modes in the cluster.
    n_bootstrap : int
        Number of bootstrap replicates.
    dim : int
        Dimension of the cluster subspace (2 for a pair of near-repeated modes).
    r2 : ndarray
        Members' correlation with the cluster subspace.
    rel_scatter : ndarray
        Members' relative pole deviations from the cluster's centre.
    contribution : float
        Modal contribution of the cluster's reference mode(s).

    Returns
    -------
    ndarray, shape (4,)
    """
    occurrence = min(1.0, n_members / float(max(1, n_bootstrap * dim)))
    decor = np.log10(max(1.0 - float(np.mean(r2)), 0.0) + FLOOR) if r2.size else 0.0
    scatter = np.log10(float(np.median(rel_scatter)) + FLOOR) if rel_scatter.size else 0.0
    contrib = float(np.clip(np.log10(max(contribution, 0.0) + FLOOR), *CONTRIBUTION_RANGE))
    return np.array([occurrence, *np.clip([decor, scatter], *LOG_RANGE), contrib])


def _memberships(X: np.ndarray, centres: np.ndarray, m: float) -> np.ndarray:
    d = np.linalg.norm(X[:, None, :] - centres[None, :, :], axis=2)  # (n, c)
    d = np.maximum(d, 1e-12)
    inv = d ** (-2.0 / (m - 1.0))
    return (inv / inv.sum(axis=1, keepdims=True)).T  # (c, n)


def physicalness(
    features: np.ndarray,
    m: float = 2.0,
    anchor_weight: float = 1.0,
    snr: bool = False,
) -> np.ndarray:
    """Anchored fuzzy c-means membership of the physical class for each cluster.

    Parameters
    ----------
    features : ndarray, shape (n_clusters, 4)
        :func:`cluster_features` of each cluster (with ``snr``: its fourth feature
        replaced by :func:`snr_feature`).
    m : float
        Fuzzifier.
    anchor_weight : float
        Copies of each prototype per cluster (1: the prototypes weigh as much as the data).
    snr : bool
        Use the prototypes and scales of the SNR feature (:data:`SNR_PHYSICAL_PROTOTYPE`,
        :data:`SNR_NOISE_PROTOTYPE`, :data:`SNR_FEATURE_SCALE`).

    Returns
    -------
    ndarray, shape (n_clusters,)
        Physicalness in [0, 1]: the membership, times ``occurrence / SPORADIC`` for a
        cluster seen by fewer than :data:`SPORADIC` of the replicates.
    """
    import skfuzzy

    features = np.atleast_2d(np.asarray(features, dtype=float))
    n = features.shape[0]
    if n == 0:
        return np.zeros(0)
    if snr:
        scale, phys_p, noise_p = SNR_FEATURE_SCALE, SNR_PHYSICAL_PROTOTYPE, SNR_NOISE_PROTOTYPE
    else:
        scale, phys_p, noise_p = FEATURE_SCALE, PHYSICAL_PROTOTYPE, NOISE_PROTOTYPE
    # a decorrelation or scatter beyond the physical prototype's is as physical as the
    # prototype (not farther from it): otherwise a noise cluster whose few members repeat
    # one pole exactly would look less like noise the tighter it is
    features = features.copy()
    features[:, 1:3] = np.maximum(features[:, 1:3], phys_p[1:3])
    X = features / scale
    protos = np.vstack([phys_p, noise_p]) / scale
    copies = max(1, int(round(anchor_weight * n)))
    data = np.vstack([X, np.repeat(protos, copies, axis=0)])
    u0 = _memberships(data, protos, m)
    centres, *_ = skfuzzy.cmeans(data.T, 2, m, error=1e-9, maxiter=300, init=u0)
    phys = int(np.argmin(np.linalg.norm(centres - protos[0], axis=1)))
    if phys == int(np.argmin(np.linalg.norm(centres - protos[1], axis=1))):
        centres = protos  # both centres collapsed onto one side: fall back to the prototypes
        phys = 0
    # a cluster seen by fewer than SPORADIC of the replicates loses membership in
    # proportion: one member of 100 replicates is never physical, whatever its shape
    minority = np.clip(features[:, 0] / SPORADIC, 0.0, 1.0)
    return _memberships(X, centres, m)[phys] * minority
