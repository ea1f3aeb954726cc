"""Fuzzy c-means clustering (Bezdek's alternating optimisation), from given memberships.

The objective is ``J = sum_i sum_k u_ik^m |x_k - v_i|^2`` over memberships ``u_ik`` (each
point's summing to 1) and centres ``v_i``. Each step sets the centres to the
``u^m``-weighted means of the points, then the memberships to
``u_ik = 1 / sum_j (d_ik / d_jk)^(2 / (m - 1))`` from the distances ``d`` to the new centres,
until the memberships move by less than a tolerance (the Frobenius norm of the change).

J. C. Bezdek, *Pattern Recognition with Fuzzy Objective Function Algorithms*, Plenum 1981.

This small loop stands in for ``skfuzzy.cmeans``, whose import pulls in
:mod:`scipy.spatial` and :mod:`scipy.sparse` (about 0.06 s of every run) for one distance
function.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["FuzzyPartition", "fuzzy_c_means", "memberships"]

DISTANCE_FLOOR = float(np.finfo(float).eps)
"""Smallest distance used (a point on a centre would otherwise divide by zero)."""


@dataclass(frozen=True)
class FuzzyPartition:
    """The result of :func:`fuzzy_c_means`.

    Attributes
    ----------
    centres : ndarray, shape (c, d)
        Cluster centres.
    memberships : ndarray, shape (c, n)
        Memberships of the points after the last step (columns sum to 1).
    iterations : int
        Steps taken.
    converged : bool
        Whether the memberships moved by less than the tolerance.
    """

    centres: np.ndarray
    memberships: np.ndarray
    iterations: int
    converged: bool


def memberships(points: np.ndarray, centres: np.ndarray, m: float) -> np.ndarray:
    """Fuzzy memberships of points to fixed centres.

    Parameters
    ----------
    points : ndarray, shape (n, d)
    centres : ndarray, shape (c, d)
    m : float
        Fuzzifier, > 1.

    Returns
    -------
    ndarray, shape (c, n)
        ``u_ik`` proportional to ``d_ik^(-2 / (m - 1))``, each column summing to 1 (distances
        below :data:`DISTANCE_FLOOR` count as that floor).
    """
    diff = points[None, :, :] - centres[:, None, :]
    d = np.maximum(np.sqrt(np.einsum("cnd,cnd->cn", diff, diff)), DISTANCE_FLOOR)
    inv = d ** (-2.0 / (m - 1.0))
    return inv / inv.sum(axis=0, keepdims=True)


def fuzzy_c_means(
    points: np.ndarray,
    initial: np.ndarray,
    m: float = 2.0,
    tolerance: float = 1e-9,
    max_iterations: int = 300,
) -> FuzzyPartition:
    """Fuzzy c-means from initial memberships.

    Parameters
    ----------
    points : ndarray, shape (n, d)
        The points, one a row.
    initial : ndarray, shape (c, n)
        Initial memberships (non-negative; each column is normalised to sum 1).
    m : float
        Fuzzifier, > 1.
    tolerance : float
        Stop when the Frobenius norm of the change of the memberships is below it.
    max_iterations : int
        Largest number of steps.

    Returns
    -------
    FuzzyPartition
        Centres of the last step and the memberships they give.
    """
    points = np.asarray(points, dtype=float)
    u = np.asarray(initial, dtype=float)
    if points.ndim != 2 or u.ndim != 2 or u.shape[1] != points.shape[0]:
        raise ValueError(f"memberships {u.shape} do not fit points {points.shape}")
    if not m > 1.0:
        raise ValueError(f"the fuzzifier must be > 1, not {m!r}")
    u = np.maximum(u / u.sum(axis=0, keepdims=True), DISTANCE_FLOOR)
    centres = np.zeros((u.shape[0], points.shape[1]))
    for step in range(1, int(max_iterations) + 1):
        weights = u**m
        centres = weights @ points / weights.sum(axis=1, keepdims=True)
        new = memberships(points, centres, m)
        moved = float(np.linalg.norm(new - u))
        u = new
        if moved < tolerance:
            return FuzzyPartition(centres, u, step, True)
    return FuzzyPartition(centres, u, int(max_iterations), False)
