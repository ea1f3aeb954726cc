"""Dense grids of many modes seen by many sensors: the benchmark's 8 x 10 grid (issue 13's
peer case: 80 modes, 40 sensors on half of the grid, 3 inputs, 3000 lines, 1 % proportional
noise) and a 7 x 12 grid with additive noise. Slow (30-60 s each on two cores)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

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
    # found in session 52 (benchmarks/results_issue13.md): 70 found and 1 false at f41e468,
    # 70 and 7 since 9bc44d3 (each replicate mode's output vector fitted over every block
    # row), 71 and 6 with the fit's poles judged by the starts nearest them, 71 and 5 with
    # a companion promoted only where the pair test judged it (a false one at 13.29 Hz);
    # the false rows left are a crowd's members (clusters of 11 reference modes at 30-31.5
    # Hz, MPC 0.04-0.49, bootstrap statistics) and two second rows of one mode each (20.73,
    # 34.41 Hz); the replicates' vectors read off the first block row again give 70 and 2
    # here but 78 and 6 on the 8 x 10 grid (77 and 3 now)
    "7x12": "a crowd's members called physical since 9bc44d3 (5 false against at most 3)",
}


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
    # one-to-one within 1 %, closest first
    used, hits = set(), 0
    for f in found:
        err = np.abs(true_hz - f) / true_hz
        for j in np.argsort(err):
            if err[j] > 0.01:
                break
            if j not in used:
                used.add(j)
                hits += 1
                break
    # 8 x 10: 5 of 80 at 0a030e1 (the sub-band above 15.5 Hz stopped its scan at n0 = 2),
    # 67 and 7 false at af5a224, 74 and 1 with the second analysis at the scan's block rows;
    # the peer, sdypy-EMA's LSCF handed the true frequencies, picked 59-60 and 1 false.
    # 7 x 12: 24 of 84 at af5a224 (its upper sub-band at q = 6), then 64 and none false, 70
    # and 1 at f41e468; more false since 9bc44d3 (KNOWN_FALSE)
    assert hits >= least, (hits, found.size)
    assert found.size - hits <= 3
