"""A band whose refinement cannot confirm a physical mode is analysed again at the order
scan's block rows when the refinement started from a reference at those rows confirms more
modes, and the analysis whose refinement confirms more physical modes is kept
(``docs/method.md`` 1, ``pipeline._retry_block_rows``, ``pipeline._retry_reference``)."""

from __future__ import annotations

from dataclasses import replace

import cases
import numpy as np
import pytest

from automodal.core import order, refine, subspace, summary
from automodal.pipeline import identify
from automodal.result import IdentifiedMode
from automodal.settings import Settings


def _mode(physical: bool, estimator: str) -> IdentifiedMode:
    return IdentifiedMode(
        id=1, frequency_hz=1.0, frequency_std_hz=0.0, frequency_ci95_hz=(1.0, 1.0),
        damping_ratio=0.01, damping_std=0.0, damping_ci95=(0.01, 0.01),
        physicalness=0.9 if physical else 0.1, physical=physical, n_members=10,
        mode_shape=np.ones(2, complex), mode_shape_std=np.zeros(2), mpc=1.0, cluster=0,
        cluster_dim=1, features={}, estimator=estimator)


def test_confirmed_and_unconfirmed_count_physical_modes_only():
    modes = [_mode(True, "ml"), _mode(True, "ml"), _mode(True, "bootstrap"),
             _mode(False, "ml"), _mode(False, "bootstrap")]
    assert summary.confirmed_modes(modes) == 2
    assert summary.unconfirmed_modes(modes) == 1


@pytest.fixture(scope="module")
def chain():
    return cases.chain10_5pct()


def _identify(chain, monkeypatch, spoil: list[bool | str],
              seen: list | None = None) -> tuple[dict, int, int]:
    """Identify ``chain``; the refinement's ``k``-th call leaves one physical mode with its
    bootstrap statistics when ``spoil[k]`` is True, every one when it is ``"all"`` (the
    calls: the first analysis's, the check at the scan's rows, the second analysis's).
    ``seen`` gets each call's modes and states. Returns the orders, the number of calls
    and the lines analysed."""
    real = summary.refine_physical_modes
    calls: list[int] = []

    def refine(modes, states, *args, **kwargs):
        if seen is not None:
            seen.append((list(modes), np.array(states)))
        out = real(modes, states, *args, **kwargs)
        if spoil[len(calls)] == "all":
            out = [replace(m, estimator="bootstrap") for m in out]
        elif spoil[len(calls)]:
            i = next(k for k, m in enumerate(out) if m.physical and m.estimator == "ml")
            out[i] = replace(out[i], estimator="bootstrap")
        calls.append(1)
        return out

    monkeypatch.setattr(summary, "refine_physical_modes", refine)
    result = identify(chain.data, Settings(seed=0, jobs=1))
    return result.orders, len(calls), result.n_lines


def test_a_band_whose_modes_are_all_confirmed_is_analysed_once(chain, monkeypatch):
    orders, calls, _ = _identify(chain, monkeypatch, [False, False])
    assert calls == 1
    assert orders["block_rows_tried"] == [orders["block_rows"]]


def test_an_unconfirmed_mode_brings_the_scan_rows_and_the_better_analysis_is_kept(
        chain, monkeypatch):
    seen: list = []
    orders, calls, n_lines = _identify(chain, monkeypatch, [True, False, False], seen)
    assert calls == 3
    # the check refines the first analysis's modes as they came from the clustering, from
    # the poles of the reference at the scan's rows, which the second analysis then uses
    (first_modes, first_states), (check_modes, check_states), (_, second_states) = seen
    assert [(m.cluster, m.frequency_hz, m.physical) for m in check_modes] == [
        (m.cluster, m.frequency_hz, m.physical) for m in first_modes]
    assert all(m.estimator == "bootstrap" for m in check_modes)
    assert check_states.shape != first_states.shape or not np.allclose(check_states,
                                                                       first_states)
    np.testing.assert_array_equal(check_states, second_states)
    first, second = orders["block_rows_tried"]
    _, ny, nu = chain.data.frf.shape
    assert second == min(subspace.scan_block_rows(orders["reference"], ny),
                         order.block_row_budget(n_lines, ny, nu))
    assert second > first
    assert orders["block_rows"] == second  # it confirmed one mode more


def test_a_second_analysis_confirming_no_more_modes_is_dropped(chain, monkeypatch):
    orders, calls, _ = _identify(chain, monkeypatch, [True, False, True])
    assert calls == 3
    first, second = orders["block_rows_tried"]
    assert second > first
    assert orders["block_rows"] == first


def test_no_second_analysis_when_the_scan_rows_poles_confirm_no_more(chain, monkeypatch):
    # the check's refinement (second call) confirms no more than the first analysis: the
    # second bootstrap is not run
    orders, calls, _ = _identify(chain, monkeypatch, [True, "all"])
    assert calls == 2
    assert orders["block_rows_tried"] == [orders["block_rows"]]


def test_a_first_analysis_whose_modes_are_mostly_unconfirmed_is_redone_without_the_check(
        chain, monkeypatch):
    # the refinement disowned every physical mode of the first analysis: its clusters are
    # no basis for the check, and the second analysis runs at once (its refinement is the
    # second call)
    seen: list = []
    orders, calls, _ = _identify(chain, monkeypatch, ["all", False], seen)
    assert calls == 2
    first, second = orders["block_rows_tried"]
    assert second > first
    assert orders["block_rows"] == second
    assert seen[1][1].shape != seen[0][1].shape or not np.allclose(seen[1][1], seen[0][1])


def test_starts_within_reach_pairs_closest_first_one_to_one_and_within_reach():
    start = np.array([-0.1 + 10j, -0.1 + 12j])
    others = np.array([-5.0 + 40j])
    # 10.05j is the closest to both starts' first; 12.2j is 2 half-bandwidths from the
    # second start (within its reach, 3); 20j is beyond every reach
    candidates = np.array([-0.1 + 20j, -0.1 + 10.05j, -0.1 + 12.2j])
    assert refine.starts_within_reach(start, others, candidates).tolist() == [1, 2]
    # one candidate for two starts: the closer start takes it, the other gets none
    near_both = np.array([-0.1 + 11.9j])
    assert refine.starts_within_reach(start, others, near_both).tolist() == [-1, 0]
    # the reach is max(3 half-bandwidths, half the gap to the nearest other pole): 1.0
    # here for both starts (2 apart)
    assert refine.starts_within_reach(start, others, np.array([-0.1 + 13.0j])).tolist() == [
        -1, 0]
    assert refine.starts_within_reach(start, others, np.array([-0.1 + 13.02j])).tolist() == [
        -1, -1]
    assert refine.starts_within_reach(start, others, np.array([])).tolist() == [-1, -1]


def test_restarted_moves_each_named_reference_mode_to_the_other_models_own():
    states = np.array([-0.5 + 10j, -0.5 - 10j, -0.1 + 12j, -0.1 - 12j, -3.0 + 0j])
    oscillatory = np.array([0, 2])
    other_states = np.array([-0.1 + 30j, -0.1 + 12.1j, -0.1 + 10.02j, -0.1 - 30j])
    other_oscillatory = np.array([2, 1, 0])  # modes at 10.02, 12.1, 30 rad/s
    modes = [replace(_mode(True, "bootstrap"), reference_mode=1),
             replace(_mode(False, "bootstrap"), reference_mode=0),
             replace(_mode(False, "bootstrap"), reference_mode=-1)]
    moved = summary.restarted(modes, states, oscillatory, other_states, other_oscillatory)
    assert [m.reference_mode for m in moved] == [1, 0, -1]
    # the reach is the refinement's: for the mode at 12 rad/s half the gap to the nearest
    # other pole (1.0 here), not its floor of 3 half-bandwidths (0.3)
    wide = np.array([-0.1 + 10.5j, -0.1 + 12.6j])
    moved = summary.restarted(modes, states, oscillatory, wide, np.array([0, 1]))
    assert [m.reference_mode for m in moved] == [1, 0, -1]
    # one pole within both modes' reach, closer to the non-physical one's in its
    # half-bandwidths (2.3 against 9): the physical mode's reference mode takes it
    middle = np.array([-0.1 + 11.1j])
    moved = summary.restarted(modes, states, oscillatory, middle, np.array([0]))
    assert [m.reference_mode for m in moved] == [0, -1, -1]
    # a model without a pole near the first mode: that mode is not refined
    lone = summary.restarted(modes, states, oscillatory, other_states[:2], np.array([1, 0]))
    assert [m.reference_mode for m in lone] == [0, -1, -1]
