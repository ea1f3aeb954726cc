"""Benchmark: the leading eigenvectors of a replicate's Schur complement, by the full
eigendecomposition or by LAPACK's subset driver.

Each bootstrap replicate's observability basis is the ``n`` leading eigenvectors of its
``L22 L22^T`` (``m = q ny`` square, :func:`automodal.core.subspace.observability_from_schur`).
This script times, for sizes ``(m, n)`` met in the family's files, numpy's stacked ``eigh``
(divide and conquer, every eigenvector) against scipy's ``eigh`` with ``subset_by_index``
(the ``evr`` driver: the ``n`` wanted eigenvectors only), one BLAS thread, best of
``--repeat`` runs of a stack of ``--stack`` random positive semi-definite matrices: on one
thread, and with the stack shared by two worker threads as the replicates' chunks are
(numpy's LAPACK calls release the GIL; scipy's ``eigh`` wrapper holds it).

Run ``python benchmarks/bench_eigh.py``; the table is written to standard output.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import scipy.linalg as sla
from threadpoolctl import threadpool_limits

SIZES = [(54, 12), (120, 20), (200, 24), (256, 12), (256, 32), (320, 40), (320, 100),
         (400, 16), (400, 50), (400, 60), (480, 20), (585, 22), (585, 30), (585, 44),
         (585, 88), (800, 60), (1080, 144)]
"""``(m, n)``: the Schur complement's size and the model order. 585 x 22 is a 39-output
dense grid's sub-band at 15 block rows (seed 381, f_08)."""


def _best(task: Callable[[], object], repeat: int) -> float:
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        task()
        best = min(best, time.perf_counter() - t0)
    return best


def _subset(stack: np.ndarray, n: int) -> None:
    """The ``n`` leading eigenpairs of each matrix of ``stack`` by the subset driver."""
    m = stack.shape[-1]
    for Si in stack:
        sla.eigh(Si, subset_by_index=[m - n, m - 1], driver="evr", check_finite=False)


def _times(S: np.ndarray, n: int, repeat: int, pool: ThreadPoolExecutor) -> list[float]:
    """Seconds per matrix: full and subset on one thread, then on two."""
    halves = [S[: len(S) // 2], S[len(S) // 2 :]]
    tasks = [lambda: np.linalg.eigh(S), lambda: _subset(S, n),
             lambda: list(pool.map(np.linalg.eigh, halves)),
             lambda: list(pool.map(_subset, halves, [n, n]))]
    return [_best(task, repeat) / len(S) for task in tasks]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--stack", type=int, default=10, help="matrices per timing")
    parser.add_argument("--repeat", type=int, default=5, help="timings; the best is kept")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    print(f"{'m':>5} {'n':>4} {'n/m':>6} {'full ms':>9} {'subset ms':>10} {'ratio':>6}"
          f" {'full 2t':>8} {'subset 2t':>10} {'ratio 2t':>9}")
    with threadpool_limits(1), ThreadPoolExecutor(2) as pool:
        for m, n in SIZES:
            X = rng.standard_normal((args.stack, m, m + 20))
            full, part, full2, part2 = _times(X @ X.swapaxes(1, 2), n, args.repeat, pool)
            print(f"{m:5d} {n:4d} {n / m:6.3f} {1e3 * full:9.2f} {1e3 * part:10.2f}"
                  f" {full / part:6.2f} {1e3 * full2:8.2f} {1e3 * part2:10.2f}"
                  f" {full2 / part2:9.2f}")


if __name__ == "__main__":
    main()
