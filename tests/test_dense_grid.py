"""Dense grids of many modes seen by many sensors: the benchmark's 8 x 10 grid (issue 13's
peer case: 80 modes, 40 sensors on half of the grid, 3 inputs, 3000 lines, 1 % proportional
noise) and a 7 x 12 grid with additive noise. Slow (30-60 s each on two cores)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.optimize import linear_sum_assignment

from automodal.cli import main
from automodal.io.readers import read_any
from automodal.pipeline import identify
from automodal.settings import Settings

GRIDS = {
    # the peer benchmark's case b
    "8x10": (["--grid", "8", "10", "--outputs", "1-40", "--inputs", "1,40,80", "--seed", "1"],
             70),
    # 84 modes, a sensor noise floor
    "7x12": (["--grid", "7", "12", "--outputs", "1-42", "--inputs", "1,42,84",
              "--noise-kind", "additive", "--seed", "11"], 60),
}

KNOWN_FALSE = {
    # case b's grid matched one to one within 1 %, closest first, at bootstrap seeds 0-3:
    # 1, 8, 7 and 7 false rows at session 52 (5-7 at 342c52f; 2 at seed 0 before 9bc44d3,
    # which fitted each replicate mode's output vector over every block row); 1, 5, 4 and 4
    # since session 53 judged the physical modes the refinement held against the refined
    # ones (the same 311 true modes in all). The rows left are members of the crowds at
    # 30-33 Hz and a promoted companion at 30.64 Hz. The 7 x 12 grid, 70 found and 7 false
    # at 342c52f, passes since session 52 (72 and 3 at every seed 0-3)
    "8x10": "false rows of crowds: 4-5 at seeds 1-3 against at most 3 (session 53)",
}


def one_to_one(found: np.ndarray, true_hz: np.ndarray, tol: float = 0.01) -> int:
    """The most found modes that can be paired one to one with true modes within ``tol``
    (relative), and of such pairings the closest (an assignment).

    Pairing each found mode in turn with the nearest true mode still free depends on the
    order and undercounts a crowd: in a variant tried on the 7 x 12 grid (session 55) a row
    at 30.03 Hz took the true 30.242 Hz mode first, and the row at 30.28 Hz, 0.14 % from
    it, was left over (72 and 4 in turn against 73 and 3 by the assignment)."""
    err = np.abs(found[:, None] - true_hz[None, :]) / true_hz[None, :]
    ok = err <= tol
    rows, cols = linear_sum_assignment(np.where(ok, err, 1.0 + err.size * tol))
    return int(ok[rows, cols].sum())


def test_one_to_one_pairs_as_many_as_it_can():
    true_hz = np.array([30.0, 30.5])
    # in turn, 30.2 would take 30.0 and leave 29.8 without a partner
    assert one_to_one(np.array([30.2, 29.8]), true_hz) == 2
    assert one_to_one(np.array([30.0, 30.01, 30.5]), true_hz) == 2
    assert one_to_one(np.array([31.0]), true_hz) == 0


@pytest.mark.slow
@pytest.mark.parametrize("grid", [
    pytest.param(g, marks=pytest.mark.xfail(reason=KNOWN_FALSE[g], strict=True))
    if g in KNOWN_FALSE else g for g in GRIDS])
def test_dense_grid(tmp_path, grid):
    args, least = GRIDS[grid]
    path = tmp_path / "grid.h5"
    res = CliRunner().invoke(main, [
        "simulate", str(path), "--system", "grid", *args, "--lines", "3000", "--noise", "0.01",
        "-q"])
    assert res.exit_code == 0, res.output
    true_hz = np.sort(json.loads((tmp_path / "grid.modes.json").read_text())["frequency_hz"])
    result = identify(read_any(path), Settings(seed=1))
    found = np.sort([m.frequency_hz for m in result.physical_modes])
    hits = one_to_one(found, true_hz)
    # 8 x 10: 5 of 80 at 0a030e1 (the sub-band above 15.5 Hz stopped its scan at n0 = 2),
    # 67 and 7 false at af5a224, 74 and 1 with the second analysis at the scan's block rows;
    # the peer, sdypy-EMA's LSCF handed the true frequencies, picked 59-60 and 1 false.
    # 7 x 12: 24 of 84 at af5a224 (its upper sub-band at q = 6), then 64 and none false, 70
    # and 1 at f41e468, 70 and 7 at 9bc44d3, 72 and 3 since session 52 (paired in turn, and
    # by the assignment since session 55)
    assert hits >= least, (hits, found.size)
    assert found.size - hits <= 3
