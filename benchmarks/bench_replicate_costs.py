"""The costs behind :func:`automodal.core.subspace.replicate_work`, on this machine.

A bootstrap replicate forms its Gram sums (a matrix product over the lines), then
eigendecomposes its Schur complement (``numpy.linalg.eigh``, ``m x m``) and its state
matrix (``numpy.linalg.eig``, ``n x n``). This prints, on one BLAS thread as the replicates
run, the time of a product per multiply-add and of each eigenproblem per ``n^3``, and their
ratio: the multiply-adds of a product that one ``n^3`` of each costs
(:data:`~automodal.core.subspace.EIG_WORK`, :data:`~automodal.core.subspace.EIGH_WORK`).

    python benchmarks/bench_replicate_costs.py
"""

from __future__ import annotations

import time

import numpy as np
from threadpoolctl import threadpool_limits


def _best(f, repeats: int = 3) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    rng = np.random.default_rng(0)
    with threadpool_limits(1):
        W, X = rng.random((100, 3000)), rng.random((3000, 20000))
        per_ma = _best(lambda: W @ X) / W.size / X.shape[1]
        print(f"product (100 x 3000) @ (3000 x 20000): {per_ma * 1e9:.3f} ns per multiply-add")
        for n in (64, 128, 216, 320, 500):
            A = rng.standard_normal((10, n, n))
            t = _best(lambda A=A: np.linalg.eig(A)) / 10
            print(f"eig  n = {n:3d}: {t * 1e3:7.1f} ms, {t / n**3 * 1e9:6.3f} ns per n^3,"
                  f" {t / n**3 / per_ma:5.1f} multiply-adds")
        for m in (128, 256, 400, 600):
            S = rng.standard_normal((10, m, m))
            S = S @ S.swapaxes(1, 2)
            t = _best(lambda S=S: np.linalg.eigh(S)) / 10
            print(f"eigh m = {m:3d}: {t * 1e3:7.1f} ms, {t / m**3 * 1e9:6.3f} ns per m^3,"
                  f" {t / m**3 / per_ma:5.1f} multiply-adds")


if __name__ == "__main__":
    main()
