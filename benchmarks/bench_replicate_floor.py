"""Benchmark: the least time a report's bootstrap could take, from its own orders.

Each bootstrap replicate of an analysed band needs the leading subspace of its ``q ny x
q ny`` Schur complement (a symmetric eigendecomposition) and the eigenvectors of its
``n x n`` state matrix (``q`` block rows, ``ny`` outputs, ``n`` states:
``docs/method.md`` 1). This script reads a report (``automodal identify FILE -o
REPORT.json``), walks its bands and sub-bands, and for every analysis in
``block_rows_tried`` times ``numpy.linalg.eigh`` of a random symmetric ``q ny`` matrix and
``numpy.linalg.eig`` of a random ``n x n`` one on one BLAS thread (the minimum of
``--repeat`` calls). It prints, per analysis, the replicates' eigenproblem time
(``n_bootstrap`` times the sum) and the totals: of every analysis that ran, and of the
reported ones alone (the floor had no band been analysed twice). Divided by the cores,
the total is what the replicates' eigenproblems alone cost with perfect sharing,
before the order scan, the Gram sums, the clustering and the refinement.

Used in ``results_issue13.md`` (session 36) to show that case b of ``bench_e2e.py`` (an
8 x 10 grid, 40 outputs, 3 inputs, 3000 lines) cannot run in 0.8 times sdypy-EMA's time
with 100 exact replicates.

Usage::

    python benchmarks/bench_replicate_floor.py REPORT.json --outputs 40 [--cores 2]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits


def analyses(orders: dict) -> list[dict]:
    """Every analysed band's ``reference``, ``block_rows`` and ``block_rows_tried``,
    sub-bands included (leaves of ``orders["sub_bands"]``)."""
    if orders.get("sub_bands"):
        return [a for sub in orders["sub_bands"] for a in analyses(sub)]
    return [{"band": orders.get("analysed_hz"), "n": int(orders["reference"]),
             "q": int(orders["block_rows"]),
             "tried": [int(q) for q in orders.get("block_rows_tried", [orders["block_rows"]])]}]


def eig_seconds(m: int, n: int, repeat: int, rng: np.random.Generator) -> float:
    """Minimum over ``repeat`` calls of ``eigh`` (``m x m``) plus ``eig`` (``n x n``)."""
    X = rng.standard_normal((m, 2 * m))
    S = X @ X.T
    A = rng.standard_normal((n, n))
    best = np.inf
    with threadpool_limits(1):
        for _ in range(repeat):
            t = time.perf_counter()
            np.linalg.eigh(S)
            np.linalg.eig(A)
            best = min(best, time.perf_counter() - t)
    return best


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("report", help="a JSON report of automodal identify")
    ap.add_argument("--outputs", type=int, required=True,
                    help="outputs of the analysed FRF (ny; inputs for a reciprocal one)")
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args(argv)
    report = json.loads(Path(a.report).read_text())
    B = int(report["settings"]["n_bootstrap"])
    rng = np.random.default_rng(0)
    ran = reported = 0.0
    print(f"{'band (Hz)':>20} {'n':>4} {'q':>3} {'q ny':>5} {'s per replicate':>16} {'x B':>7}")
    for an in analyses(report["settings"]["orders"]):
        band = "" if an["band"] is None else f"{an['band'][0]:.1f}-{an['band'][1]:.1f}"
        for q in an["tried"]:
            t = eig_seconds(q * a.outputs, an["n"], a.repeat, rng)
            ran += B * t
            reported += B * t if q == an["q"] else 0.0
            mark = " (reported)" if q == an["q"] else ""
            print(f"{band:>20} {an['n']:>4} {q:>3} {q * a.outputs:>5} {t:>16.4f}"
                  f" {B * t:>7.2f}{mark}")
    print(f"replicates' eigenproblems, every analysis: {ran:.2f} s on one core,"
          f" {ran / a.cores:.2f} s on {a.cores}")
    print(f"the reported analyses alone: {reported:.2f} s on one core,"
          f" {reported / a.cores:.2f} s on {a.cores}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
