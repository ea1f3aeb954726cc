"""Unit tests of :mod:`automodal.core.clustering` on small hand-made arrays.

MOC vectors are replaced by unit vectors of a small space (``e_0 .. e_5``) so that every
correlation is known by hand: ``rho(cos t e_0 + sin t e_3, span{e_0}) = cos^2 t``.
"""

from __future__ import annotations

import numpy as np
import pytest

from automodal.core.clustering import (
    TRASHBOX,
    ReferenceSubspaces,
    assign,
    coalescent_groups,
    physical_candidates,
    principal_correlation,
    rank_within_replicate,
    reference_subspaces,
    split_weak_members,
    trim,
)
from automodal.core.correlation import subspace_correlation

DIM = 6
E = np.eye(DIM, dtype=complex)


def _mix(a: int, b: int, cos2: float) -> np.ndarray:
    """Unit vector with ``|<e_a, v>|^2 = cos2`` and the rest on ``e_b``."""
    return np.sqrt(cos2) * E[:, a] + np.sqrt(1.0 - cos2) * E[:, b]


def _lists_equal(got: list[np.ndarray], expected: list[list[int]]) -> bool:
    return [list(map(int, g)) for g in got] == expected


# ---------------------------------------------------------------------------------------
# physical_candidates
# ---------------------------------------------------------------------------------------

# -3 + 4j: |l| = 5 exactly, zeta = 3/5 = 0.6 exactly (a Pythagorean pole)
P345 = -3.0 + 4.0j


def test_physical_candidates_basic_cases():
    poles = np.array(
        [
            -0.1 + 10.0j,  # stable, zeta 0.01, in band: candidate
            +0.1 + 10.0j,  # unstable
            -0.1 - 10.0j,  # the conjugate (Im < 0)
            -10.0 + 0.0j,  # real pole
            0.0 + 10.0j,  # zeta = 0 exactly (undamped): not 0 < zeta
            -5.0 + 5.0j,  # zeta = 0.707: overdamped for zeta_max 0.2
            -0.1 + 1000.0j,  # above the band
            -0.001 + 0.5j,  # below the band
        ]
    )
    got = physical_candidates(poles, (1.0, 100.0))
    np.testing.assert_array_equal(got, [True, False, False, False, False, False, False, False])


def test_physical_candidates_zeta_max_is_strict():
    band = (1.0, 10.0)
    assert not physical_candidates(np.array([P345]), band, zeta_max=0.6)[0]
    assert physical_candidates(np.array([P345]), band, zeta_max=0.6 + 1e-9)[0]
    assert not physical_candidates(np.array([P345]), band)[0]  # default zeta_max 0.2


@pytest.mark.parametrize(
    "band,inside",
    [
        ((5.0, 10.0), True),  # on the lower edge: inclusive
        ((1.0, 5.0), True),  # on the upper edge: inclusive
        ((5.0 + 1e-9, 10.0), False),
        ((1.0, 5.0 - 1e-9), False),
    ],
)
def test_physical_candidates_band_edges_are_inclusive(band, inside):
    # band on the natural frequency |l| = 5, not on Im l = 4
    assert physical_candidates(np.array([P345]), band, zeta_max=0.7)[0] == inside


def test_physical_candidates_band_uses_natural_frequency_not_damped():
    # Im l = 4 is in (3.5, 4.5) but |l| = 5 is not
    assert not physical_candidates(np.array([P345]), (3.5, 4.5), zeta_max=0.7)[0]


# ---------------------------------------------------------------------------------------
# coalescent_groups
# ---------------------------------------------------------------------------------------


def test_coalescent_groups_within_one_half_power_bandwidth():
    # half-power bandwidth: -Re l = 1 for each
    poles = np.array([-1.0 + 100.0j, -1.0 + 100.5j, -1.0 + 103.0j])
    assert _lists_equal(coalescent_groups(poles), [[0, 1], [2]])


def test_coalescent_groups_distance_equal_to_bandwidth_does_not_join():
    poles = np.array([-1.0 + 100.0j, -1.0 + 101.0j])  # distance 1.0 = bandwidth: strict <
    assert _lists_equal(coalescent_groups(poles), [[0], [1]])
    assert _lists_equal(coalescent_groups(poles, alpha=1.0 + 1e-9), [[0, 1]])


def test_coalescent_groups_use_the_smaller_bandwidth():
    # distance sqrt(4^2 + 2^2) = 4.47; min(1, 5) = 1 keeps them apart (max(1, 5) would join)
    poles = np.array([-1.0 + 100.0j, -5.0 + 102.0j])
    assert _lists_equal(coalescent_groups(poles), [[0], [1]])
    assert _lists_equal(coalescent_groups(poles, alpha=4.5), [[0, 1]])


def test_coalescent_groups_transitive_chain():
    # a-b 0.8, b-c 0.8 (both < 1) but a-c 1.6: one group through b
    poles = np.array([-1.0 + 101.6j, -1.0 + 100.0j, -1.0 + 100.8j, -1.0 + 200.0j])
    assert _lists_equal(coalescent_groups(poles), [[0, 1, 2], [3]])


def test_coalescent_groups_resolution_joins_lightly_damped_neighbours():
    poles = np.array([-0.01 + 50.0j, -0.01 + 50.5j])  # 0.5 apart, bandwidth 0.01
    assert _lists_equal(coalescent_groups(poles), [[0], [1]])
    assert _lists_equal(coalescent_groups(poles, resolution=0.6), [[0, 1]])
    assert _lists_equal(coalescent_groups(poles, resolution=0.5), [[0], [1]])  # strict


def test_coalescent_groups_are_ordered_by_natural_frequency():
    poles = np.array([-1.0 + 300.0j, -1.0 + 100.0j, -1.0 + 200.0j, -1.0 + 100.2j])
    got = coalescent_groups(poles)
    assert _lists_equal(got, [[1, 3], [2], [0]])  # each group sorted, lowest first


def test_coalescent_groups_of_nothing():
    assert coalescent_groups(np.zeros(0, dtype=complex)) == []


# ---------------------------------------------------------------------------------------
# split_weak_members
# ---------------------------------------------------------------------------------------


def test_split_weak_members_ratio_is_inclusive():
    groups = [np.array([0, 1, 2]), np.array([3])]
    contribution = np.array([1.0, 0.2, 0.25, 0.01])
    got = split_weak_members(groups, contribution, ratio=0.25)
    # 0.25 >= 0.25 * 1.0 stays; 0.2 leaves as a singleton; a lone weak mode stays itself
    assert _lists_equal(got, [[0, 2], [1], [3]])


def test_split_weak_members_strongest_need_not_be_first():
    groups = [np.array([4, 5, 6])]
    contribution = np.array([0, 0, 0, 0, 0.1, 0.9, 0.5])
    assert _lists_equal(split_weak_members(groups, contribution), [[5, 6], [4]])


def test_split_weak_members_keeps_groups_of_equals():
    groups = [np.array([0, 1]), np.array([2, 3, 4])]
    contribution = np.array([0.3, 0.3, 0.5, 0.4, 0.2])
    assert _lists_equal(split_weak_members(groups, contribution), [[0, 1], [2, 3, 4]])


# ---------------------------------------------------------------------------------------
# reference_subspaces
# ---------------------------------------------------------------------------------------


def _ref() -> ReferenceSubspaces:
    """Cluster 0 = span{e0}, cluster 1 = span{e1, e2} (capacity 2), noise = span{e3, e4}."""
    o_ref = E[:, :4]
    candidate = np.array([True, True, True, False])
    return reference_subspaces(o_ref, candidate, E[:, [4]], [np.array([0]), np.array([1, 2])])


def test_reference_subspaces_bases_noise_and_capacity():
    ref = _ref()
    assert [b.shape for b in ref.bases] == [(DIM, 1), (DIM, 2)]
    np.testing.assert_array_equal(ref.dims, [1, 2])
    assert ref.capacity == [1, 2]
    # the noise subspace: the non-candidate e3 and the real pole's e4, nothing else
    assert ref.noise_basis.shape == (DIM, 2)
    rho_noise = subspace_correlation(ref.noise_basis, E)
    np.testing.assert_allclose(rho_noise, [0, 0, 0, 1, 1, 0], atol=1e-14)
    rho_1 = subspace_correlation(ref.bases[1], E)
    np.testing.assert_allclose(rho_1, [0, 1, 1, 0, 0, 0], atol=1e-14)


def test_reference_subspaces_explicit_capacity_and_no_noise():
    o_ref = E[:, :3]
    ref = reference_subspaces(
        o_ref, np.ones(3, dtype=bool), np.zeros((DIM, 0)), [np.array([0, 1]), np.array([2])],
        capacity=[1, 1],
    )
    np.testing.assert_array_equal(ref.dims, [1, 1])  # a group of two that takes one mode
    assert ref.bases[0].shape == (DIM, 2)
    assert ref.noise_basis.shape == (DIM, 0)


# ---------------------------------------------------------------------------------------
# assign
# ---------------------------------------------------------------------------------------


def test_assign_threshold_best_cluster_and_noise():
    ref = _ref()
    o = np.column_stack(
        [
            E[:, 0],  # cluster 0, rho 1
            _mix(1, 5, 0.9),  # cluster 1 (via e1), rho 0.9 (e5 is in no subspace)
            _mix(0, 5, 0.7),  # below tau = 0.8: Trashbox
            _mix(0, 3, 0.3),  # noise e3 wins
            (0.1 * E[:, 0] + np.sqrt(0.99) * E[:, 2]),  # best cluster is 1 (0.99 vs 0.01)
            E[:, 4],  # pure noise (real pole)
        ]
    )
    labels, rho = assign(o, np.arange(6), ref, threshold=0.8)
    np.testing.assert_array_equal(labels, [0, 1, TRASHBOX, TRASHBOX, 1, TRASHBOX])
    # rho: with the chosen cluster, or with the best one for Trashbox modes
    np.testing.assert_allclose(rho, [1.0, 0.9, 0.7, 0.3, 0.99, 0.0], atol=1e-12)


def test_assign_threshold_is_inclusive():
    ref = _ref()
    o = _mix(0, 5, 0.8)[:, None]
    rho = float(subspace_correlation(ref.bases[0], o)[0])  # 0.8 up to rounding
    labels, _ = assign(o, np.zeros(1, dtype=int), ref, threshold=rho)
    assert labels[0] == 0  # rho >= tau
    labels, _ = assign(o, np.zeros(1, dtype=int), ref, threshold=np.nextafter(rho, 1.0))
    assert labels[0] == TRASHBOX


def test_assign_noise_tie_goes_to_the_trashbox():
    ref = _ref()
    o = ((E[:, 0] + E[:, 3]) / np.sqrt(2))[:, None]  # rho_0 = rho_noise = 0.5
    labels, _ = assign(o, np.zeros(1, dtype=int), ref, threshold=0.4)
    assert labels[0] == TRASHBOX  # needs rho_c > rho_noise, strictly


def test_assign_noise_that_wins_overrides_a_passing_cluster():
    ref = _ref()
    o = _mix(0, 3, 0.45)[:, None]  # rho_0 0.45 >= tau 0.4, rho_noise 0.55
    labels, _ = assign(o, np.zeros(1, dtype=int), ref, threshold=0.4)
    assert labels[0] == TRASHBOX


def test_assign_capacity_keeps_the_best_per_replicate_and_cluster():
    ref = _ref()  # dims [1, 2]
    cols = [
        (_mix(0, 5, 0.90), 0),  # 0: cluster 0, replicate 0, 2nd best
        (_mix(1, 5, 0.85), 0),  # 1: cluster 1, replicate 0, 3rd best -> Trashbox
        (_mix(0, 5, 0.95), 0),  # 2: cluster 0, replicate 0, best
        (_mix(0, 5, 0.82), 1),  # 3: cluster 0, replicate 1, alone -> kept
        (_mix(2, 5, 0.97), 0),  # 4: cluster 1, replicate 0, best
        (_mix(0, 5, 0.85), 0),  # 5: cluster 0, replicate 0, 3rd -> Trashbox
        (_mix(1, 5, 0.92), 0),  # 6: cluster 1, replicate 0, 2nd -> kept (dim 2)
        (_mix(1, 5, 0.81), 1),  # 7: cluster 1, replicate 1 -> kept
    ]
    o = np.column_stack([c for c, _ in cols])
    replicate = np.array([r for _, r in cols])
    labels, rho = assign(o, replicate, ref, threshold=0.8)
    np.testing.assert_array_equal(labels, [TRASHBOX, TRASHBOX, 0, 0, 1, TRASHBOX, 1, 1])
    np.testing.assert_allclose(rho, [0.9, 0.85, 0.95, 0.82, 0.97, 0.85, 0.92, 0.81], atol=1e-12)
    # the rule itself: no replicate gives a cluster more modes than its dimension
    for c, d in enumerate(ref.dims):
        for r in np.unique(replicate):
            assert np.count_nonzero((labels == c) & (replicate == r)) <= d


def test_assign_capacity_does_not_depend_on_input_order():
    ref = _ref()
    o = np.column_stack([_mix(0, 5, v) for v in (0.83, 0.99, 0.91)])
    for perm in ([0, 1, 2], [2, 0, 1], [1, 2, 0]):
        labels, _ = assign(o[:, perm], np.zeros(3, dtype=int), ref)
        kept = np.array(perm)[labels == 0]
        assert list(kept) == [1]  # the 0.99 one, wherever it sits


def test_assign_without_clusters_or_modes():
    empty = ReferenceSubspaces(groups=[], bases=[], noise_basis=E[:, :1], capacity=[])
    labels, rho = assign(E[:, :3], np.zeros(3, dtype=int), empty)
    np.testing.assert_array_equal(labels, TRASHBOX)
    np.testing.assert_array_equal(rho, 0.0)
    labels, rho = assign(np.zeros((DIM, 0)), np.zeros(0, dtype=int), _ref())
    assert labels.shape == (0,) and rho.shape == (0,)


# ---------------------------------------------------------------------------------------
# rank_within_replicate
# ---------------------------------------------------------------------------------------


def test_rank_within_replicate_by_hand():
    # replicate 0: |l| 3, 1, 2.5 -> ranks 2, 0, 1; replicate 1: 2, 5 -> 0, 1; replicate 4: 0
    poles = np.array([3.0j, 1.0j, 2.0j, 2.5j, 5.0j, 7.0j])
    replicate = np.array([0, 0, 1, 0, 1, 4])
    np.testing.assert_array_equal(rank_within_replicate(poles, replicate), [2, 0, 0, 1, 1, 0])


def test_rank_within_replicate_uses_natural_frequency():
    # Im of the first is smaller (4 < 4.5) but |l| is larger (5 > 4.5)
    poles = np.array([-3.0 + 4.0j, 4.5j])
    np.testing.assert_array_equal(rank_within_replicate(poles, np.array([2, 2])), [1, 0])


def test_rank_within_replicate_one_mode_each_is_all_zero():
    poles = np.array([5.0j, 1.0j, 3.0j])
    np.testing.assert_array_equal(rank_within_replicate(poles, np.array([2, 0, 1])), 0)


# ---------------------------------------------------------------------------------------
# trim
# ---------------------------------------------------------------------------------------


def _cluster(n: int, angles: np.ndarray, poles: np.ndarray):
    o = np.column_stack([np.cos(t) * E[:, 0] + np.sin(t) * E[:, 1] for t in angles])
    return o, poles, np.arange(n)


def test_trim_sends_a_decorrelated_member_to_the_trashbox():
    angles = np.r_[0.01 * np.arange(9), 0.6]  # member 9 is 0.6 rad off (r^2 about 0.7)
    poles = -1.0 + 1j * (100.0 + 0.001 * np.arange(10))
    o, poles, rep = _cluster(10, angles, poles)
    labels, r2 = trim(np.zeros(10, dtype=int), o, poles, rep, np.array([1]))
    np.testing.assert_array_equal(labels, [0] * 9 + [TRASHBOX])
    assert r2[9] == 0.0
    assert np.all(r2[:9] > 0.99) and np.all(r2[:9] <= 1.0 + 1e-12)


def test_trim_sends_a_far_pole_to_the_trashbox():
    angles = 0.001 * np.arange(10)
    poles = -1.0 + 1j * (100.0 + 0.001 * np.arange(10))
    poles[3] = -1.0 + 101.0j  # 1 rad/s off; the others spread over 0.009
    o, poles, rep = _cluster(10, angles, poles)
    labels, _ = trim(np.zeros(10, dtype=int), o, poles, rep, np.array([1]))
    expected = np.zeros(10, dtype=int)
    expected[3] = TRASHBOX
    np.testing.assert_array_equal(labels, expected)


def test_trim_keeps_identical_members_and_does_not_modify_its_input():
    o = np.tile(E[:, [0]], (1, 6))
    poles = np.full(6, -1.0 + 100.0j)
    labels_in = np.zeros(6, dtype=int)
    labels, r2 = trim(labels_in, o, poles, np.arange(6), np.array([1]))
    np.testing.assert_array_equal(labels, 0)  # rounding-level spreads trim nothing
    np.testing.assert_allclose(r2, 1.0, atol=1e-12)
    labels_in2 = np.r_[np.zeros(9, dtype=int), TRASHBOX]
    o2, p2, rep2 = _cluster(
        10, np.r_[0.01 * np.arange(9), 0.6], -1.0 + 100.0j + 0.001j * np.arange(10)
    )
    before = labels_in2.copy()
    trim(labels_in2, o2, p2, rep2, np.array([1]))
    np.testing.assert_array_equal(labels_in2, before)


def test_trim_leaves_clusters_of_fewer_than_three_alone():
    o = np.column_stack([E[:, 0], E[:, 1]])  # orthogonal and far apart: still kept
    poles = np.array([-1.0 + 100.0j, -1.0 + 200.0j])
    labels, r2 = trim(np.zeros(2, dtype=int), o, poles, np.arange(2), np.array([1]))
    np.testing.assert_array_equal(labels, [0, 0])
    np.testing.assert_allclose(np.sort(r2), [0.0, 1.0], atol=1e-12)


def test_trim_measures_pole_deviation_within_each_rank():
    # a repeated pair: replicates 0-5 give a mode near 100 rad/s, replicates 0-4 also one
    # near 110 (11 members). Within each rank the poles agree to 0.005 rad/s, so nothing is
    # trimmed; pooled without ranks, the median would sit at 100 and the five modes near
    # 110 would be far outliers.
    low = -1.0 + 1j * (100.0 + 0.001 * np.arange(6))
    high = -1.0 + 1j * (110.0 + 0.001 * np.arange(5)[::-1])
    poles = np.r_[low, high]
    rep = np.r_[np.arange(6), np.arange(5)]
    angles = np.linspace(0.0, np.pi / 2, poles.size)  # shapes anywhere in span{e0, e1}
    o = np.column_stack([np.cos(t) * E[:, 0] + np.sin(t) * E[:, 1] for t in angles])
    labels, r2 = trim(np.zeros(poles.size, dtype=int), o, poles, rep, np.array([2]))
    np.testing.assert_array_equal(labels, 0)
    np.testing.assert_allclose(r2, 1.0, atol=1e-12)  # 2-dimensional principal subspace


def test_trim_uses_the_cluster_dimension():
    # ten members along e0 and two along e1, poles identical: in two dimensions all
    # correlate fully; in one, the two along e1 are far from the principal line.
    angles = np.r_[np.zeros(10), np.full(2, np.pi / 2)]
    o = np.column_stack([np.cos(t) * E[:, 0] + np.sin(t) * E[:, 1] for t in angles])
    poles = np.full(12, -1.0 + 100.0j)
    rep = np.r_[np.arange(10), np.arange(2)]
    labels2, _ = trim(np.zeros(12, dtype=int), o, poles, rep, np.array([2]))
    np.testing.assert_array_equal(labels2, 0)
    labels1, _ = trim(np.zeros(12, dtype=int), o, poles, rep, np.array([1]))
    np.testing.assert_array_equal(labels1, [0] * 10 + [TRASHBOX] * 2)


def test_trim_treats_each_cluster_separately():
    angles = np.r_[0.01 * np.arange(9), 0.6]
    o0, p0, rep0 = _cluster(10, angles, -1.0 + 1j * (100.0 + 0.001 * np.arange(10)))
    o1 = np.tile(E[:, [2]], (1, 4))
    p1 = np.full(4, -2.0 + 300.0j)
    o = np.hstack([o0, o1])
    poles = np.r_[p0, p1]
    rep = np.r_[rep0, np.arange(4)]
    labels_in = np.r_[np.zeros(10, dtype=int), np.ones(4, dtype=int)]
    labels, _ = trim(labels_in, o, poles, rep, np.array([1, 1]))
    np.testing.assert_array_equal(labels, [0] * 9 + [TRASHBOX] + [1] * 4)


@pytest.mark.parametrize("d, m", [(60, 100), (222, 100), (12, 5), (30, 1)])
@pytest.mark.parametrize("dim", [1, 2])
def test_principal_correlation_is_the_svds_whichever_gram_it_uses(d, m, dim):
    """Members wider or taller than they are many: the smaller Gram matrix gives the
    correlations with the leading singular subspace that the SVD gives."""
    rng = np.random.default_rng(d + m + dim)
    signal = rng.standard_normal((d, dim)) + 1j * rng.standard_normal((d, dim))
    o = signal @ rng.standard_normal((dim, m)) + 0.2 * (
        rng.standard_normal((d, m)) + 1j * rng.standard_normal((d, m)))
    o /= np.linalg.norm(o, axis=0)
    u = np.linalg.svd(o, full_matrices=False)[0][:, :dim]
    np.testing.assert_allclose(principal_correlation(o, dim), subspace_correlation(u, o),
                               rtol=0, atol=1e-12)
