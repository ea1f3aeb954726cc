"""A band whose refinement cannot confirm a physical mode is analysed again at the order
scan's block rows, and the analysis whose refinement confirms more physical modes is kept
(``docs/method.md`` 1, ``pipeline._retry_block_rows``)."""

from __future__ import annotations

from dataclasses import replace

import cases
import numpy as np
import pytest

from automodal.core import order, subspace, summary
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


def _identify(chain, monkeypatch, spoil: list[bool]) -> tuple[dict, int, int]:
    """Identify ``chain``; the refinement's ``k``-th call leaves one physical mode with its
    bootstrap statistics when ``spoil[k]``. Returns the orders, the number of calls and
    the lines analysed."""
    real = summary.refine_physical_modes
    calls: list[int] = []

    def refine(modes, *args, **kwargs):
        out = real(modes, *args, **kwargs)
        if spoil[len(calls)]:
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
    orders, calls, n_lines = _identify(chain, monkeypatch, [True, False])
    assert calls == 2
    first, second = orders["block_rows_tried"]
    _, ny, nu = chain.data.frf.shape
    assert second == min(subspace.scan_block_rows(orders["reference"], ny),
                         order.block_row_budget(n_lines, ny, nu))
    assert second > first
    assert orders["block_rows"] == second  # it confirmed one mode more


def test_a_second_analysis_confirming_no_more_modes_is_dropped(chain, monkeypatch):
    orders, calls, _ = _identify(chain, monkeypatch, [True, True])
    assert calls == 2
    first, second = orders["block_rows_tried"]
    assert second > first
    assert orders["block_rows"] == first
