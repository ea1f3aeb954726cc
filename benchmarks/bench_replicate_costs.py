"""What a bootstrap replicate's eigenproblems cost against its projection, on this machine.

A replicate forms its Gram sums (a matrix product over the lines), then eigendecomposes its
Schur complement (``numpy.linalg.eigh``, ``m x m``) and its state matrix
(``numpy.linalg.eig``, ``n x n``). ``automodal.core.subspace.replicate_work``, which decides
when a band is split, counts the projection only. This prints, on one BLAS thread as the
replicates run, the time of a product per multiply-add and of each eigenproblem per ``n^3``,
and their ratio: how many multiply-adds of a product one ``n^3`` of each costs
(``benchmarks/results_issue13.md``, session 43: adding them to the work was measured and
withheld).

    python benchmarks/bench_replicate_costs.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_eigh import _best  # noqa: E402


def main() -> None:
    rng = np.random.default_rng(0)
    with threadpool_limits(1):
        W, X = rng.random((100, 3000)), rng.random((3000, 20000))
        per_ma = _best(lambda: W @ X, 3) / W.size / X.shape[1]
        print(f"product (100 x 3000) @ (3000 x 20000): {per_ma * 1e9:.3f} ns per multiply-add")
        for name, solve, sizes in (("eig ", np.linalg.eig, (64, 128, 216, 320, 500)),
                                   ("eigh", np.linalg.eigh, (128, 256, 400, 600))):
            for n in sizes:
                A = rng.standard_normal((10, n, n))
                if solve is np.linalg.eigh:
                    A = A @ A.swapaxes(1, 2)
                t = _best(lambda A=A, solve=solve: solve(A), 3) / 10
                print(f"{name} n = {n:3d}: {t * 1e3:7.1f} ms, {t / n**3 * 1e9:6.3f} ns per n^3,"
                      f" {t / n**3 / per_ma:5.1f} multiply-adds")


if __name__ == "__main__":
    main()
