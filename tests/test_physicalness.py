"""Unit tests of :mod:`automodal.core.physicalness` on hand-made features."""

from __future__ import annotations

import numpy as np
import pytest

from automodal.core.physicalness import (
    FEATURE_NAMES,
    FEATURE_SCALE,
    NOISE_PROTOTYPE,
    PHYSICAL_PROTOTYPE,
    cluster_features,
    physicalness,
)

P, N = PHYSICAL_PROTOTYPE, NOISE_PROTOTYPE
# the direction in which each feature gets "more physical"
BETTER = np.sign(P - N)  # occurrence up, decorrelation down, scatter down, contribution up


# ---------------------------------------------------------------------------------------
# cluster_features
# ---------------------------------------------------------------------------------------


def test_cluster_features_by_hand():
    f = cluster_features(
        n_members=150,
        n_bootstrap=100,
        dim=2,
        r2=np.array([0.99, 0.999]),  # mean 0.9945 -> 1 - mean = 5.5e-3
        rel_scatter=np.array([1e-2, 1e-4, 1e-3]),  # median 1e-3 (not the mean, 3.7e-3)
        contribution=0.1,
    )
    assert f.shape == (4,) and len(FEATURE_NAMES) == 4
    np.testing.assert_allclose(f, [0.75, np.log10(5.5e-3), -3.0, -1.0], rtol=1e-9)


def test_cluster_features_occurrence_divides_by_replicates_times_dimension():
    r2, sc = np.array([0.9]), np.array([1e-3])
    assert cluster_features(50, 100, 1, r2, sc, 1.0)[0] == pytest.approx(0.5)
    assert cluster_features(50, 100, 2, r2, sc, 1.0)[0] == pytest.approx(0.25)
    assert cluster_features(1, 100, 1, r2, sc, 1.0)[0] == pytest.approx(0.01)
    assert cluster_features(250, 100, 2, r2, sc, 1.0)[0] == 1.0  # capped at 1
    assert cluster_features(3, 0, 1, r2, sc, 1.0)[0] == 1.0  # no division by zero


def test_cluster_features_clip_and_floor():
    # perfect correlation and zero scatter: log10(1e-12) = -12, clipped to -8
    f = cluster_features(10, 10, 1, np.ones(3), np.zeros(3), 1.0)
    np.testing.assert_allclose(f, [1.0, -8.0, -8.0, 0.0], atol=1e-9)
    # a mean correlation above 1 by rounding counts as perfect, not as NaN
    f = cluster_features(10, 10, 1, np.array([1.0 + 1e-15]), np.array([1e-3]), 1.0)
    assert f[1] == -8.0
    # contribution: log10 clipped to [-4, 0.5]
    assert cluster_features(1, 1, 1, np.ones(1), np.ones(1), 0.0)[3] == -4.0
    assert cluster_features(1, 1, 1, np.ones(1), np.ones(1), -3.0)[3] == -4.0
    assert cluster_features(1, 1, 1, np.ones(1), np.ones(1), 1e3)[3] == 0.5
    # fully decorrelated members and a 100 % scatter: log10(1) = 0, the top of the range
    f = cluster_features(1, 1, 1, np.zeros(2), np.array([1.0, 50.0, 0.5]), 1.0)
    np.testing.assert_allclose(f[1:3], [0.0, 0.0], atol=1e-9)


def test_cluster_features_of_empty_member_arrays():
    f = cluster_features(0, 100, 1, np.zeros(0), np.zeros(0), 0.5)
    assert f[0] == 0.0 and f[1] == 0.0 and f[2] == 0.0
    assert np.all(np.isfinite(f))


# ---------------------------------------------------------------------------------------
# physicalness: the anchoring
# ---------------------------------------------------------------------------------------


def test_physical_prototype_alone_is_physical():
    assert physicalness(P)[0] == pytest.approx(1.0, abs=1e-6)


def test_noise_prototype_alone_is_noise():
    assert physicalness(N)[0] == pytest.approx(0.0, abs=1e-6)


def test_empty_file_gives_empty_result():
    assert physicalness(np.zeros((0, 4))).shape == (0,)


@pytest.mark.parametrize("n,spread,shift", [(12, 0.5, 0.0), (40, 1.0, 0.0), (40, 0.5, 0.2)])
def test_a_file_of_noise_like_clusters_has_no_physical_one(n, spread, shift):
    # plain two-class c-means would call about half of these physical. The last case sits
    # a fifth of the way towards the physical prototype: with one copy of each prototype
    # instead of n (no anchoring weight), 21 of its 40 clusters came out physical.
    rng = np.random.default_rng(0)
    centre = shift * P + (1.0 - shift) * N
    feats = centre + spread * FEATURE_SCALE * rng.standard_normal((n, 4))
    feats[:, 0] = np.clip(feats[:, 0], 0.0, 1.0)
    phys = physicalness(feats)
    assert phys.shape == (n,)
    assert np.all(phys < 0.5), phys
    assert np.all((phys >= 0) & (phys <= 1))


def test_a_file_of_physical_like_clusters_is_all_physical():
    rng = np.random.default_rng(1)
    feats = P + 0.5 * FEATURE_SCALE * rng.standard_normal((8, 4))
    feats[:, 0] = np.clip(feats[:, 0], 0.0, 1.0)
    assert np.all(physicalness(feats) > 0.5)


def test_a_mixed_file_is_split_the_right_way():
    rng = np.random.default_rng(2)
    phys_like = P + 0.3 * FEATURE_SCALE * rng.standard_normal((3, 4))
    noise_like = N + 0.3 * FEATURE_SCALE * rng.standard_normal((9, 4))
    feats = np.vstack([phys_like, noise_like])
    feats[:, 0] = np.clip(feats[:, 0], 0.0, 1.0)
    phys = physicalness(feats)
    assert np.all(phys[:3] > 0.9) and np.all(phys[3:] < 0.1)


def test_one_member_cluster_with_typical_features_is_not_physical():
    # one member of 100 replicates, correlation 0.9, 0.1 % scatter, 1 % of the FRF
    f = cluster_features(1, 100, 1, np.array([0.9]), np.array([1e-3]), 0.01)
    assert physicalness(f)[0] < 0.5
    # the same member among physical clusters of the same file: still not physical
    feats = np.vstack([f, P, P + [0.0, -0.5, 0.3, -0.1]])
    assert physicalness(feats)[0] < 0.5


def test_one_member_cluster_with_perfect_other_features_is_not_physical():
    """One member of 100 replicates, otherwise the physical prototype (was 0.91)."""
    f = cluster_features(1, 100, 1, np.array([1.0 - 1e-5]), np.array([10**-4.5]), 1.0)
    assert physicalness(f)[0] < 0.5


def test_noise_cluster_with_tiny_pole_scatter_is_not_physical():
    """A noise cluster whose members repeat one pole (scatter 10^-7.5; was 0.95)."""
    assert physicalness(np.array([0.4, -1.0, -7.5, -2.3]))[0] < 0.5


# ---------------------------------------------------------------------------------------
# physicalness: monotonicity and determinism
# ---------------------------------------------------------------------------------------


def _sweep(base: np.ndarray, feature: int, others: np.ndarray | None) -> np.ndarray:
    """Physicalness of ``base`` with ``feature`` stepped from the noise to the physical
    prototype's value, alone or in a file with ``others``."""
    values = np.linspace(N[feature], P[feature], 25)
    out = []
    for v in values:
        x = base.copy()
        x[feature] = v
        feats = x[None, :] if others is None else np.vstack([x, others])
        out.append(physicalness(feats)[0])
    return np.array(out)


@pytest.mark.parametrize("feature", range(4), ids=list(FEATURE_NAMES))
@pytest.mark.parametrize("t", [0.25, 0.5, 0.75], ids=["noise-side", "middle", "physical-side"])
@pytest.mark.parametrize("context", ["alone", "in-a-file"])
def test_better_feature_never_lowers_physicalness(feature, t, context):
    base = t * P + (1.0 - t) * N
    others = None if context == "alone" else np.vstack([P + 0.1 * FEATURE_SCALE, N - 0.1])
    phys = _sweep(base, feature, others)
    assert np.all(np.diff(phys) >= -1e-9), np.round(phys, 4)
    assert phys[-1] > phys[0]  # and the feature matters


def test_better_occurrence_never_lowers_physicalness_over_its_whole_range():
    # from the physical prototype: occurrence 0 .. 1 (1 is the prototype's own value)
    phys = []
    for occ in np.linspace(0.0, 1.0, 21):
        phys.append(physicalness(np.array([occ, *P[1:]]))[0])
    assert np.all(np.diff(phys) >= -1e-9)


def test_physicalness_is_deterministic_and_order_equivariant():
    rng = np.random.default_rng(5)
    t = rng.uniform(0, 1, size=(7, 1))
    feats = t * P + (1 - t) * N + 0.2 * FEATURE_SCALE * rng.standard_normal((7, 4))
    a = physicalness(feats)
    b = physicalness(feats.copy())
    np.testing.assert_array_equal(a, b)
    perm = rng.permutation(7)
    np.testing.assert_allclose(physicalness(feats[perm]), a[perm], atol=1e-6)


def test_physicalness_accepts_one_feature_vector_and_stays_in_unit_interval():
    for x in (P, N, 0.5 * (P + N), np.array([0.0, 0.0, 0.0, -4.0]), np.array([1, -8, -8, 0.5])):
        phys = physicalness(x)
        assert phys.shape == (1,)
        assert 0.0 <= phys[0] <= 1.0
