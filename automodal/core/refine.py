"""Maximum-likelihood refinement of chosen poles, and their covariance.

The subspace estimate is consistent but not efficient: on noisy data its poles err by
several times what the noise allows, and a bootstrap over frequency lines measures the
spread of re-fits of one noise realization, not that error. Given the noise model, the
poles of the modes called physical are refined by weighted nonlinear least squares (the
maximum-likelihood estimate for Gaussian noise) of a pole-residue model,

    H(s) = sum_r [ R_r / (s - lambda_r) + conj(R_r) / (s - conj(lambda_r)) ]
           + sum_q (the same for the fixed poles nu_q) + sum_k c_k s^k,      s = i omega,

with residues per FRF entry (linear, eliminated by variable projection), the chosen poles
``lambda_r`` free, the other poles ``nu_q`` of the over-sized model kept fixed (they carry
the structure the chosen modes do not explain) and residual terms for the modes outside
the band. The Gauss-Newton steps use Kaufman's Jacobian (Golub and Pereyra 1973; Kaufman
1975). The poles' covariance is the larger of the noise model's inverse Fisher information
and a clustered sandwich (which sees what the noise model misses), with a small-sample
correction. Both treat the fixed pole pairs of the band's resonances as what they are,
estimates with their own uncertainty (nuisance parameters; broader or out-of-band poles
are background, as the residual terms are): the information and the scores of the
refined poles are the efficient ones, with the part a fixed neighbour's pole could
explain projected out (the Schur complement of the joint information). A refined mode
beside a fixed neighbour it overlaps with is then as uncertain as the pair's data allow;
without it, the intervals of modes within three half-bandwidths of another covered 85 %
of the true values on the calibration seed 252 (isolated modes 93 %).

The weighting is separable: the noise variance of line ``k`` and entry ``e`` is fitted as
``v_k c_e`` (a two-way model of its logarithm), so every entry shares one basis. Where the
noise model's variance is not separable (noise proportional to ``|H|``: each entry's
anti-resonances and own strong modes), the fit is weighted least squares with the wrong
weights, still consistent, and its covariance under the noise model is ``A^-1 B A^-1``
(``A`` the information of the separable weights, ``B`` the scores' covariance with the
full variance), not ``A^-1``: the sandwich's median ratio to ``A^-1`` was 5 on the
proportional-noise files of seed 252 (1.1 with additive noise). The sandwich still
accounts for what the noise model itself misses.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any, TypeVar

import numpy as np
import scipy.linalg as sla

from automodal.core.noise import VARIANCE_ACCURACY
from automodal.core.parallel import PARALLEL_MIN_FLOPS, freeing_map
from automodal.core.shrinkage import shrunk

T = TypeVar("T")

MAX_ITERATIONS = 10
"""Gauss-Newton (Levenberg-Marquardt) iterations at most. From the subspace estimate an
isolated mode's fit converges in a few. A joint fit of many overlapping poles (dense grids,
30-40 free poles) converges only linearly: where the model's misfit is systematic (the other
poles held fixed), each step moves the poles 0.2-0.6 standard deviations along a curved
valley, for as many steps as allowed, and the fit is restarted each time a pole strays.
Those further steps do not bring the estimates nearer the truth: on the 64 files of the
calibration seeds 281 and 283 the intervals' coverage was the same with 10, 30 and 150
iterations (frequency 0.907, 0.905, 0.903; damping 0.919, 0.922, 0.922; recall and false
modes identical), while the files' total time was 207, 214 and 246 s and the slowest file
10.3, 15.5 and 28.0 s. The full Golub-Pereyra Jacobian instead of Kaufman's did not
converge faster."""

RELATIVE_TOLERANCE = 1e-12
"""Stop when an accepted step lowers the cost by less than this share of it."""

STEP_TOLERANCE = 1e-3
"""Or when an accepted step moves every pole parameter by less than this share of its
standard deviation (from the Gauss-Newton matrix): further steps change nothing a report
shows, and on a 23 x 3 dense grid of 3000 lines they took most of 64 iterations."""

MAX_MOVE = 3.0
"""A refined pole may always move this many of its half-power half-bandwidths
(``|Re lambda|``) from the subspace estimate, and further only within its territory (see
:data:`TERRITORY`); one that moves further (a fit that drifted to a neighbour or into
noise) is not refined, and keeps its bootstrap statistics."""

TERRITORY = 0.5
"""Beyond :data:`MAX_MOVE` half-bandwidths, a refined pole may move up to this share of
the distance from its start to the nearest other pole of the model (free or fixed): the
half-way point, past which it would be explaining its neighbour's mode. A subspace
estimate of a low-order model can be biased by more than three half-bandwidths (seed 208,
f_02: a 12 x 1 displacement chain with 5 % additive noise, modes at 8.75 and 14.16 Hz
started 3.4 % and 4.4 % high); the fit finds them, and the territory still stops a
duplicate cluster's pole from collapsing onto the mode next to it."""

MAX_DAMPING_CHANGE = 3.0
"""Nor may its half-bandwidth change by more than this factor: a pole that collapses onto
one noisy line (or spreads over the band) is no longer the mode the bootstrap found."""


CLUSTER_LINES = 4
"""Adjacent lines whose errors the robust covariance lets be correlated: spectra of windowed
records share leakage over the window's main lobe (4 lines for a Hann window), so an H1
estimate's errors at neighbouring lines are not independent. Measured on a 20 x 3 H1 file
(8 averages, seed 208, f_02): frequency errors of 10-30 standard deviations with the noise
model alone, 3-5 with one-line clusters, 1.5-2.5 with four."""

RESIDUAL_POWERS = (-2, -1, 0, 1, 2)
"""Powers of ``s`` in the basis, with complex coefficients: the residual terms of the modes
outside the band (below it ``1/s^2`` in displacement, ``1/s`` in velocity, a constant in
acceleration; above it a constant, ``s``, ``s^2`` likewise). At high SNR an out-of-band
mode's smooth tail, left to the nearest fixed poles, biased in-band poles by tens of their
standard deviations (measured on a velocity grid whose upper modes lie above the band)."""

LOCAL_HALF_BANDWIDTHS = 5.0
"""Lines within this many half-bandwidths of a pole set the dispersion its statistics are
judged against (:func:`pair_verdicts`): its resonance and the shoulders where a
neighbour's bias shows."""

MIN_LOCAL_LINES = 8
"""At least this many lines for that judgement (a pole narrower than the line spacing)."""

DUPLICATE_HALF_BANDWIDTHS = 2.0
"""Refined poles closer than this many half-bandwidths are tested as one mode against two
(:func:`pair_verdicts`); it is also how far the refinement's neighbourhood reaches
(:data:`automodal.core.summary.NEAR_POLE`)."""

SEPARABLE_TOLERANCE = 0.05
"""The noise model's covariance of the refined poles takes the noise variance's departure
from its separable model (:func:`separable_ratio`) into account when the ratio leaves
``1 +- SEPARABLE_TOLERANCE`` somewhere; within it, the inverse Fisher information of the
separable weights is that covariance to this share, and the cost of the exact one is
saved."""

RESIDUE_RANK_EDGE = 3.0
"""A direction of a residue matrix counts (:func:`residue_shapes`) when its singular value
exceeds this many times the largest its estimation error alone would give (the
Marchenko-Pastur edge ``sigma (sqrt(ny) + sqrt(nu))``), as for the outputs' rank
(:data:`automodal.core.whitening.RANK_EDGE`)."""

DUPLICATE_LEVEL = 0.01
"""False-alarm rate of that test: a second pole is kept when one pole explains the data
worse than this chance under the noise model. Measured on the calibration seeds 211, 214,
215, 218 (165 refined pairs within three half-bandwidths, all of distinct true modes): the
smallest ratio of the statistic to its degrees of freedom was 5.2 (a 34 x 3 dense grid);
the split resonance of the 10-DOF chain test case (5 % noise) gives 1.6, against 2.2 at
this level for its 5 entries."""


@dataclass(frozen=True)
class PoleRefinement:
    """The refined poles and what the fit says of them.

    Attributes
    ----------
    poles : ndarray, shape (m,)
        Refined continuous-time poles (rad/s), in the order given; the starting pole where
        ``refined`` is False.
    covariance : ndarray, shape (m, 2, 2)
        Covariance of ``(Re, Im)`` of each pole: the robust sandwich where it exceeds the
        noise model's covariance of the estimate, else the latter, both with the fixed
        pole pairs' uncertainty accounted for (see the module's notes); NaN where
        ``refined`` is False.
    dispersion : ndarray, shape (m,)
        Trace of the robust (line-clustered sandwich) covariance over that of the noise
        model's (about 1 when the model and the noise model agree; more when the residual
        exceeds the noise or is correlated across entries).
    refined : ndarray of bool, shape (m,)
        Whether each pole was refined.
    iterations : int
        Gauss-Newton iterations of the last fit.
    residues : ndarray, shape (m, ny, nu), complex
        Residue ``R_r`` of each refined pole per FRF entry, in the data's units, from the
        same fit (every other pole in the basis); NaN where ``refined`` is False.
    residue_variance : ndarray, shape (m,)
        Variance (``E |error|^2``) of each residue entry under the separable noise model,
        in units of that entry's noise (the residue divided by the square root of the
        entry's separable variance, :func:`separable_weights`); large where the pole's
        terms are nearly collinear with another's. NaN where ``refined`` is False.
    entry_variance : ndarray, shape (m, ny, nu)
        Variance (``E |error|^2``, data units) of each residue entry under the noise
        variance as given, entry by entry: the residues are linear in the data, so the
        separable weights' estimate has the variance ``G V G^T`` whatever the weights.
        NaN where ``refined`` is False.
    held : ndarray of bool, shape (m,)
        Poles the fit held at their starts: asked to (``refine_poles``' ``held``), or taken
        out of reach, unstable or out of width by the fit (every pole where there was no
        fit). A pole not ``refined`` but not ``held`` was fitted, and its covariance came
        out singular.
    """

    poles: np.ndarray
    covariance: np.ndarray
    dispersion: np.ndarray
    refined: np.ndarray
    iterations: int
    residues: np.ndarray
    residue_variance: np.ndarray
    entry_variance: np.ndarray
    held: np.ndarray

    def frequency_damping(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Natural frequency (Hz) and damping ratio of each pole with their standard
        deviations (delta method: ``f = |lambda| / 2 pi``, ``zeta = -Re lambda / |lambda|``).

        Returns
        -------
        f, f_std, zeta, zeta_std : ndarray, shape (m,)
            A standard deviation is NaN where the covariance gives no variance (NaN, or a
            negative one: an indefinite matrix, as the sandwich of a pole the data hardly
            determine can be, is no covariance).
        """
        lam = self.poles
        a = np.abs(lam)
        s, w = lam.real, lam.imag
        grad_f = np.stack([s, w], axis=-1) / (2 * np.pi * a[:, None])
        grad_z = np.stack([-(w**2), s * w], axis=-1) / (a[:, None] ** 3)
        var_f = np.einsum("mi,mij,mj->m", grad_f, self.covariance, grad_f)
        var_z = np.einsum("mi,mij,mj->m", grad_z, self.covariance, grad_z)
        var_f, var_z = (np.where(v >= 0.0, v, np.nan) for v in (var_f, var_z))
        return a / (2 * np.pi), np.sqrt(var_f), -s / a, np.sqrt(var_z)


def separation(poles: np.ndarray) -> np.ndarray:
    """``(m, m)``: how far apart each pair of ``poles`` lies, in half-bandwidths (the
    larger of the two ``|Re p|``); ``inf`` for distinct undamped poles, ``nan`` for an
    undamped pole and itself."""
    poles = np.asarray(poles, dtype=complex).ravel()
    half = np.abs(poles.real)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.abs(poles[:, None] - poles[None, :]) / np.maximum(half[:, None],
                                                                    half[None, :])


def within_reach(poles: np.ndarray) -> np.ndarray:
    """``(m, m)``: which pairs of ``poles`` lie within :data:`DUPLICATE_HALF_BANDWIDTHS`
    half-bandwidths of each other (:func:`separation`), each pole with itself included
    where its damping is not zero."""
    return separation(poles) < DUPLICATE_HALF_BANDWIDTHS


def separable_weights(variance: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Line variance ``v_k`` and entry variance ``c_e`` of ``log var ~ log v_k + log c_e``.

    The least-squares fit of a complete two-way table: row means and column means.

    Parameters
    ----------
    variance : ndarray, shape (N, E)
        Positive noise variance per line and entry.

    Returns
    -------
    line : ndarray, shape (N,)
    entry : ndarray, shape (E,)
        With ``line[k] * entry[e]`` the separable variance.
    """
    L = np.log(variance)
    row = L.mean(axis=1)
    col = L.mean(axis=0) - row.mean()
    return np.exp(row), np.exp(col)


def separable_ratio(variance: np.ndarray) -> np.ndarray:
    """The noise variance over its separable model (:func:`separable_weights`), ``(N, E)``:
    1 everywhere for additive noise of a level per entry; for noise proportional to
    ``|H|`` it is far from 1 wherever an entry's magnitude does not follow the others'
    (its anti-resonances, its own strong modes).

    Parameters
    ----------
    variance : ndarray, shape (N, ...)
        Positive noise variance per line and entry.
    """
    V = np.asarray(variance, float).reshape(np.shape(variance)[0], -1)
    line, entry = separable_weights(V)
    return V / (line[:, None] * entry[None, :])


def _stack(X: np.ndarray) -> np.ndarray:
    """Complex ``(N, k)`` as real ``(2N, k)``: real parts over imaginary parts."""
    return np.concatenate([X.real, X.imag], axis=0)


def _pair_columns(s: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """The two real-coefficient columns of each pole pair, ``(N, 2k)`` complex:
    ``1/(s - lambda) + 1/(s - conj lambda)`` (the residue's real part) and
    ``i [1/(s - lambda) - 1/(s - conj lambda)]`` (its imaginary part), per pole in turn.
    A real system's FRF is ``R/(s - lambda) + conj(R)/(s - conj lambda)``: tying the two
    terms keeps the pair's smooth conjugate term from becoming a free column (those are
    nearly collinear across poles)."""
    a = 1.0 / (s[:, None] - lam[None, :])
    b = 1.0 / (s[:, None] - lam.conj()[None, :])
    out = np.empty((s.size, 2 * lam.size), dtype=complex)
    out[:, 0::2] = a + b
    out[:, 1::2] = 1j * (a - b)
    return out


def _pair_derivatives(s: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """Derivatives of :func:`_pair_columns`, ``(N, 4k)`` complex: per pole, the two columns
    with respect to ``Re lambda``, then the two with respect to ``Im lambda``."""
    a2 = 1.0 / (s[:, None] - lam[None, :]) ** 2
    b2 = 1.0 / (s[:, None] - lam.conj()[None, :]) ** 2
    out = np.empty((s.size, 4 * lam.size), dtype=complex)
    out[:, 0::4] = a2 + b2  # d(first) / d Re
    out[:, 1::4] = 1j * (a2 - b2)  # d(second) / d Re
    out[:, 2::4] = 1j * (a2 - b2)  # d(first) / d Im
    out[:, 3::4] = -(a2 + b2)  # d(second) / d Im
    return out


def _fixed_columns(s: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """Columns of the fixed poles (pairs as in :func:`_pair_columns`, real poles one real
    column) and the residual terms (:data:`RESIDUAL_POWERS`), ``(N, k)`` complex with real
    coefficients."""
    fixed = np.asarray(fixed, dtype=complex)
    scale = np.maximum(np.abs(fixed), 1e-300)
    real = np.abs(fixed.imag) <= 1e-9 * scale
    pairs = fixed[(fixed.imag > 0) & ~real]
    x = s / np.sqrt(np.abs(s[0] * s[-1]))  # i omega over the band's geometric centre
    powers = np.stack([x**k for k in RESIDUAL_POWERS], axis=1)
    cols = [_pair_columns(s, pairs), 1.0 / (s[:, None] - fixed[real].real[None, :]),
            powers, 1j * powers]
    return np.concatenate(cols, axis=1)


@dataclass(frozen=True)
class _Problem:
    """The weighted data, stacked real, with the fixed part of the basis projected out
    once (Frisch-Waugh-Lovell: the free poles' residues and residual are those of the full
    regression).

    The stacked rows are the real parts of the lines, then their imaginary parts: the two
    halves of every sum over rows (:meth:`each_half`) are formed apart, on two workers when
    ``pmap`` is a parallel ``map``, and added in that order, so the numbers never depend on
    the workers."""

    s: np.ndarray  # i omega, (N,)
    sw: np.ndarray  # square root of the line weights, (N,)
    Qf: np.ndarray  # orthonormal basis of the weighted fixed columns, (2N, p)
    Yf: np.ndarray  # whitened data, fixed part projected out, (2N, E)
    pmap: Callable = map  # the halves' map: the built-in one, or a thread pool's

    @classmethod
    def make(cls, s: np.ndarray, sw: np.ndarray, Y: np.ndarray, fixed: np.ndarray,
             pmap: Callable = map) -> _Problem:
        Qf = _orthonormal(_stack(sw[:, None] * _fixed_columns(s, fixed)))
        Ys = _stack(Y)
        return cls(s=s, sw=sw, Qf=Qf, Yf=Ys - Qf @ (Qf.T @ Ys), pmap=pmap)

    def off_fixed(self, X: np.ndarray) -> np.ndarray:
        """Stacked ``X`` with the fixed columns projected out."""
        return X - self.Qf @ (self.Qf.T @ X)

    @property
    def halves(self) -> tuple[slice, slice]:
        """The stacked rows of the real parts, and of the imaginary parts."""
        n = self.s.size
        return slice(0, n), slice(n, 2 * n)

    def each_half(self, task: Callable[[int], T]) -> list[T]:
        """``[task(0), task(1)]`` (the real rows', the imaginary rows'), through ``pmap``."""
        return list(self.pmap(task, (0, 1)))

    def summed(self, task: Callable[[int], T]) -> T:
        """``task(0) + task(1)``: a sum over the stacked rows, half by half."""
        real, imaginary = self.each_half(task)
        return real + imaginary


def _column_space(Phi: np.ndarray, full: bool) -> tuple[np.ndarray, int]:
    """Left singular vectors of ``Phi`` with its columns normalised (all of them with
    ``full``), and how many span its column space numerically (singular values above
    1e-10 of the largest)."""
    norms = np.linalg.norm(Phi, axis=0)
    U, sv, _ = np.linalg.svd(Phi / np.where(norms > 0, norms, 1.0)[None, :],
                             full_matrices=full)
    return U, int(np.sum(sv > sv[0] * 1e-10)) if sv.size else 0


def _orthonormal(Phi: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the column space of ``Phi`` (columns normalised first; columns
    that add nothing numerically are dropped)."""
    U, rank = _column_space(Phi, full=False)
    return U[:, :rank] if Phi.shape[1] else U


def _left_out(R: np.ndarray) -> np.ndarray:
    """Orthonormal directions ``(t, v)`` of ``R^t`` outside the column space of ``R``
    ``(t, k)``, as :func:`_orthonormal` would cut it: with ``Q`` orthonormal, ``Q R``'s
    basis is ``Q (I - V V^T)``."""
    if R.shape[1] == 0:
        return np.eye(R.shape[0])
    U, rank = _column_space(R, full=True)
    return U[:, rank:]


def _qr(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Thin QR of a real ``A``: ``numpy.linalg.qr``'s factors (the same LAPACK Householder
    routines, the same numbers), from scipy's wrapper, which measured 1.75 times faster on
    the refinement's 8776 x 76 stacks."""
    return sla.qr(A, mode="economic", check_finite=False)


def _off_basis(
    prob: _Problem, cols: np.ndarray, Qp: np.ndarray | None = None
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The complex columns ``cols`` ``(N, k)`` stacked real and projected off the fixed
    part, then off ``Qp`` when given: per half of the rows, the columns and their
    projection. Each projection's coefficients are summed over the two halves first."""
    parts = (cols.real, cols.imag)
    h = prob.halves
    out = list(parts)
    for Q in [prob.Qf] if Qp is None else [prob.Qf, Qp]:
        coef = prob.summed(lambda i, Q=Q, X=out: Q[h[i]].T @ X[i])
        out = prob.each_half(lambda i, Q=Q, X=out, coef=coef: X[i] - Q[h[i]] @ coef)
    return list(parts), out


def _fit(
    prob: _Problem, free: np.ndarray
) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    """Residues of the free poles and residual of the linear fit at given free poles.

    Returns ``cost, C, R, Qp``: the squared residual summed, the real coefficients
    ``(2m, E)`` of :func:`_pair_columns` (``Re``, ``Im`` of each residue in turn), the
    stacked residual ``(2N, E)`` and the orthonormal basis of the free columns off the
    fixed ones (one Householder QR of all rows: where the columns are numerically
    dependent, its basis and so the residual depend on how the QR is made, and this is
    the one the statistics were measured with).
    """
    h = prob.halves
    _, parts = _off_basis(prob, prob.sw[:, None] * _pair_columns(prob.s, free))
    Qp, Rt, norms = _normalised_qr(np.vstack(parts))
    QY = prob.summed(lambda i: Qp[h[i]].T @ prob.Yf[h[i]])
    R = np.empty_like(prob.Yf)

    def residual(i: int) -> float:
        R[h[i]] = prob.Yf[h[i]] - Qp[h[i]] @ QY
        return float(np.sum(R[h[i]] * R[h[i]]))

    return prob.summed(residual), _coefficients(Rt, QY, norms), R, Qp


def _normalised_qr(P: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One Householder QR of ``P`` with its columns normalised: ``Q``, ``R`` and the
    columns' norms (1 for a zero column)."""
    norms = np.linalg.norm(P, axis=0)
    norms = np.where(norms > 0, norms, 1.0)
    Q, R = _qr(P / norms[None, :])
    return Q, R, norms


def _coefficients(R: np.ndarray, QY: np.ndarray, norms: np.ndarray) -> np.ndarray:
    """The least-squares coefficients of the columns whose :func:`_normalised_qr` is
    ``(Q, R, norms)``, from ``QY = Q^T Y`` (a least-norm solve where ``R`` is singular)."""
    try:
        C = np.linalg.solve(R, QY)
    except np.linalg.LinAlgError:
        C = np.linalg.lstsq(R, QY, rcond=None)[0]
    return C / norms[:, None]


def _coefficient_rows(free: np.ndarray, C: np.ndarray) -> np.ndarray:
    """The coefficient row ``(4m, E)`` that multiplies each derivative column of
    :func:`_pair_derivatives`."""
    return np.repeat(C.reshape(free.size, 2, -1)[:, None], 2, axis=1).reshape(4 * free.size, -1)


def _jacobian_parts(
    prob: _Problem, free: np.ndarray, C: np.ndarray, Qp: np.ndarray
) -> tuple[list[np.ndarray], list[np.ndarray], np.ndarray]:
    """Derivative columns ``D`` (``(4m)`` columns, per half of the stacked rows), the same
    projected off the whole basis (``PD``, per half) and the coefficient row that
    multiplies each (``(4m, E)``): Kaufman's Jacobian of parameter ``t`` (``Re lambda_r``
    or ``Im lambda_r``) is ``-sum PD[:, a] Cx[a]^T`` over its two columns ``a``."""
    D, PD = _off_basis(prob, prob.sw[:, None] * _pair_derivatives(prob.s, free), Qp)
    return D, PD, _coefficient_rows(free, C)


def _normal_equations(
    prob: _Problem, parts: tuple[list[np.ndarray], list[np.ndarray], np.ndarray],
    R: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Newton normal matrix ``J^T J`` and gradient ``J^T r`` in the real parameters
    ``(Re lambda_1, Im lambda_1, ...)`` (variable projection with Kaufman's Jacobian), from
    :func:`_jacobian_parts` and the fit's residual ``R``."""
    h = prob.halves
    D, PD, Cx = parts
    # R is orthogonal to the basis: D^T R = PD^T R
    gram, dr = zip(*prob.each_half(lambda i: (PD[i].T @ PD[i], D[i].T @ R[h[i]])))
    W = (gram[0] + gram[1]) * (Cx @ Cx.T)
    u = np.sum(Cx * (dr[0] + dr[1]), axis=1)
    # parameter t owns columns 2t and 2t + 1 of D
    n = Cx.shape[0] // 2
    normal = W.reshape(n, 2, n, 2).sum(axis=(1, 3))
    grad = -u.reshape(n, 2).sum(axis=1)
    return normal, grad


def _gauss_newton(
    prob: _Problem, free: np.ndarray, max_iterations: int,
    strayed: Callable[[np.ndarray], np.ndarray] | None = None,
    enough: float = -np.inf,
) -> tuple[np.ndarray, int, float]:
    """Levenberg-Marquardt on the free poles; returns them, the iterations taken and the
    cost there.

    ``strayed(poles)`` (a boolean mask) ends the fit as soon as a pole has left what a
    refinement may do: the caller holds it fixed and fits again, so the remaining
    iterations would be wasted. ``enough`` as for :func:`_levenberg_marquardt`, whose
    loop this is on the explicit fit (:func:`_fit`)."""
    def fit(poles: np.ndarray) -> tuple[float, tuple]:
        cost, *state = _fit(prob, poles)
        return cost, tuple(state)

    def normal(poles: np.ndarray, state: tuple) -> tuple[np.ndarray, np.ndarray]:
        C, R, Qp = state
        return _normal_equations(prob, _jacobian_parts(prob, poles, C, Qp), R)

    return _levenberg_marquardt(fit, normal, free, max_iterations, strayed, enough)


def _levenberg_marquardt(
    fit: Callable[[np.ndarray], tuple[float, Any]],
    normal_equations: Callable[[np.ndarray, Any], tuple[np.ndarray, np.ndarray]],
    free: np.ndarray, max_iterations: int,
    strayed: Callable[[np.ndarray], np.ndarray] | None = None,
    enough: float = -np.inf,
    inside: Callable[[np.ndarray], bool] | None = None,
) -> tuple[np.ndarray, int, float]:
    """:func:`_gauss_newton` on any evaluation of the variable-projection problem:
    ``fit(poles)`` gives the cost and a state, ``normal_equations(poles, state)`` the
    Gauss-Newton matrix and gradient there. A step to poles where ``inside`` is false is
    refused as one that raises the cost is (a shorter one is tried): the fit stays in that
    region.

    The fit ends once the cost is below ``enough``: a caller that only asks whether the
    cost can get that low (:func:`pair_verdicts`) has its answer, since accepted steps
    never raise the cost (the fit run to its end gives the same answer, but for a
    comparison within the last bit of ``enough``; the residue's rank, judged after it, is
    judged at the pole where it stopped)."""
    cost, state = fit(free)
    damping = 1e-3
    it = 0
    for _ in range(max_iterations):
        if cost < enough:
            break
        it += 1
        normal, grad = normal_equations(free, state)
        diag = np.diag(normal).copy()
        diag = np.where(diag > 0, diag, 1.0)
        improved = False
        for _ in range(12):
            try:
                step = np.linalg.solve(normal + damping * np.diag(diag), -grad)
            except np.linalg.LinAlgError:
                damping *= 10.0
                continue
            trial = free + step[0::2] + 1j * step[1::2]
            if inside is not None and not inside(trial):
                damping *= 10.0
                continue
            t_cost, t_state = fit(trial)
            if np.isfinite(t_cost) and t_cost <= cost:
                gain = cost - t_cost
                free, cost, state = trial, t_cost, t_state
                damping = max(damping / 10.0, 1e-9)
                # step in standard deviations: sqrt(0.5 / J^T J) per parameter
                moved = np.max(np.abs(step) * np.sqrt(2.0 * diag))
                improved = (gain > RELATIVE_TOLERANCE * max(cost, 1e-300)
                            and moved > STEP_TOLERANCE
                            and not (strayed is not None and strayed(free).any()))
                break
            damping *= 10.0
        if not improved:
            break
    return free, it, cost


GRAM_ACCURACY = 1e-6
"""A :class:`_GramFit` evaluation is used only where its cost's rounding error bound is
below this share of the cost; elsewhere the fit is formed line by line (:func:`_fit`'s)."""

GRAM_CONDITION = 1e8
"""Nor where the free columns' normalised Gram matrix is worse conditioned than this (two
poles about 1e-3.5 half-bandwidths apart: 1.6e7 at 1e-3, 1.6e9 at 1e-4 on a 4-DOF chain),
or where less than ``1 / GRAM_CONDITION`` of a free column's square norm is left off the
basis: the Gram matrices then keep fewer than eight digits of what decides the fit."""


@dataclass(frozen=True)
class _GramFit:
    """The fit of a few free poles to whitened data through small Gram matrices.

    The model's other columns span ``Qf`` (the fixed part, orthonormal) and
    ``Qt (I - V V^T)``: ``Qt`` (orthonormal, off ``Qf``) with the directions ``V`` (in its
    coordinates, orthonormal) left out. ``Yf`` is the data off ``Qf``, ``QtY = Qt^T Yf``.
    So :func:`pair_verdicts` tests a pair against all the other tested poles that are
    still in the model (``Qt`` of all of them; ``V`` the directions of the pair and of the
    duplicates found before) without forming each test's basis (the fixed part's and the
    others' columns, orthonormal over all the lines: 6.6 ms per test on a 21 x 3 dense grid
    of 2000 lines, seed 797 f_29).

    Each evaluation reads ``[Qf, Qt]`` and ``Yf`` once, for the free poles' columns ``X``
    and their derivatives ``D`` together (``Z = [X D]``): ``Z``'s Gram matrix off the
    other columns and ``Z^T`` times the data off them give the cost, the residues and
    Kaufman's Gauss-Newton matrix and gradient as :func:`_fit` and
    :func:`_normal_equations` do; those form every projected column and the residual
    explicitly (four passes over the basis and three over the data per iteration, 17 ms
    per test there). The cost is a difference of sums of squares, ``yy - b^T G^-1 b``: its
    rounding error is about ``eps (yy + |b| |Yf|)``, so where that bound is not below
    :data:`GRAM_ACCURACY` of the cost (the tested poles explain nearly all of data whose
    dynamic range is 150 dB), or where ``G`` is ill-conditioned or the free columns lie
    almost within the basis (:data:`GRAM_CONDITION`), the evaluation forms the projected
    columns and the residual over all the lines and fits them with a Householder QR, as
    :func:`_fit` does. Both agree with :func:`_fit` to rounding (``tests/test_refine.py``).
    """

    s: np.ndarray  # i omega, (N,)
    sw: np.ndarray  # square root of the line weights, (N,)
    B: np.ndarray  # [Qf, Qt], (2N, p + t)
    p: int  # columns of Qf in B
    V: np.ndarray  # directions of Qt left out of the basis, (t, v)
    Yf: np.ndarray  # data off Qf, (2N, E)
    QtY: np.ndarray  # Qt^T Yf, (t, E)
    VQY: np.ndarray  # V^T QtY, (v, E)
    yy: float  # the data's sum of squares off the basis
    scale: float  # |Yf|, the data's norm off Qf: the rounding of every product with it

    @classmethod
    def make(cls, prob: _Problem, Qt: np.ndarray | None = None,
             QtY: np.ndarray | None = None) -> _GramFit:
        """The fit against ``prob``'s fixed part and all of ``Qt`` (``QtY = Qt^T Yf``).
        The data's sum of squares off that basis is formed line by line, once."""
        if Qt is None or QtY is None:
            Qt, QtY = prob.Qf[:, :0], np.zeros((0, prob.Yf.shape[1]))
        rest = prob.Yf - Qt @ QtY
        return cls(s=prob.s, sw=prob.sw, B=np.hstack([prob.Qf, Qt]), p=prob.Qf.shape[1],
                   V=np.zeros((QtY.shape[0], 0)), Yf=prob.Yf, QtY=QtY,
                   VQY=np.zeros((0, QtY.shape[1])), yy=float(np.sum(rest * rest)),
                   scale=float(np.linalg.norm(prob.Yf)))

    def without(self, V: np.ndarray) -> _GramFit:
        """The same fit with the directions ``V`` of ``Qt`` left out of the basis (in
        place of this fit's own)."""
        VQY = V.T @ self.QtY
        yy = self.yy + float(np.sum(VQY * VQY) - np.sum(self.VQY * self.VQY))
        return replace(self, V=V, VQY=VQY, yy=yy)

    def _grams(self, Z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``Z``'s Gram matrix off the basis, its product with the data off the basis, its
        coefficients on the basis (``B^T Z``) and its columns' whole square norms."""
        A = self.B.T @ Z
        Af, At = A[: self.p], A[self.p:]
        Vt = self.V.T @ At
        ZtZ = Z.T @ Z
        ZZ = ZtZ - Af.T @ Af - At.T @ At + Vt.T @ Vt
        ZY = Z.T @ self.Yf - At.T @ self.QtY + Vt.T @ self.VQY
        return ZZ, ZY, A, np.diag(ZtZ)

    def _data_off_basis(self) -> np.ndarray:
        """The data off the basis, line by line ``(2N, E)``: the same for every
        evaluation, so formed at the first and kept (a :meth:`without` is a new fit, with
        its own). On a 20 x 3 dense grid of 3000 lines (seed 1337 f_02) it was half of
        each explicit evaluation's time."""
        Y = self.__dict__.get("_Y")
        if Y is None:
            Y = self.Yf - self.B[:, self.p:] @ (self.QtY - self.V @ self.VQY)
            object.__setattr__(self, "_Y", Y)  # a cache, not a field: frozen stays true
        return Y

    def _explicit(self, X: np.ndarray, A: np.ndarray) -> tuple[float, np.ndarray]:
        """Cost and coefficients of the free columns ``X`` (``A = B^T X``) as :func:`_fit`
        finds them: the columns and the data off the basis formed line by line, the columns
        normalised and fitted by one Householder QR."""
        Qt = self.B[:, self.p:]
        kept = A[self.p:] - self.V @ (self.V.T @ A[self.p:])
        P = X - self.B[:, : self.p] @ A[: self.p] - Qt @ kept
        Y = self._data_off_basis()
        Qp, Rt, norms = _normalised_qr(P)
        QY = Qp.T @ Y
        R = Y - Qp @ QY
        return float(np.sum(R * R)), _coefficients(Rt, QY, norms)

    def fit(self, free: np.ndarray, derivatives: bool = True) -> tuple[float, tuple]:
        """The cost at ``free`` and the state :meth:`normal_equations` needs (without
        ``derivatives``, the cost only): the coefficients ``(2m, E)`` of
        :func:`_pair_columns`, ``Z``'s Gram matrix off the basis, ``Z^T`` times the data off
        it, the free columns' normalised Gram matrix and their norms."""
        k = 2 * free.size
        cols = [_pair_columns(self.s, free)]
        if derivatives:
            cols.append(_pair_derivatives(self.s, free))
        Z = _stack(self.sw[:, None] * np.concatenate(cols, axis=1))
        ZZ, ZY, A, whole = self._grams(Z)
        whole, left = whole[:k], np.diag(ZZ)[:k]
        norms = np.sqrt(np.maximum(left, 0.0))
        norms = np.where(norms > 0, norms, 1.0)
        G = ZZ[:k, :k] / np.outer(norms, norms)
        b = ZY[:k] / norms[:, None]
        C = None
        cond = np.linalg.cond(G)
        try:  # rounding can leave a nearly singular G indefinite: then line by line
            L = np.linalg.cholesky(G)
        except np.linalg.LinAlgError:
            L = None
        if np.all(left > whole / GRAM_CONDITION) and cond < GRAM_CONDITION and L is not None:
            c = sla.solve_triangular(L, b, lower=True, check_finite=False)
            cost = self.yy - float(np.sum(c * c))
            # the rounding of yy - c^T c: G's (its condition) and b's (the products with
            # the data, each column's norm over its part off the basis)
            ratio = float(np.sqrt(np.max(whole / left)))
            bound = 64.0 * np.finfo(float).eps * (
                cond * self.yy + np.linalg.norm(c) * self.scale * ratio)
            if bound < GRAM_ACCURACY * cost:
                C = sla.solve_triangular(L.T, c, lower=False, check_finite=False)
                C = C / norms[:, None]
        if C is None:
            cost, C = self._explicit(Z[:, :k], A[:, :k])
        return cost, (C, ZZ, ZY, G, norms)

    def normal_equations(self, free: np.ndarray, state: tuple) -> tuple[np.ndarray, np.ndarray]:
        """Gauss-Newton matrix and gradient at ``free``, as :func:`_normal_equations`: the
        derivative columns off the basis and off the free columns
        (``PD^T PD = Z_dd - M^T G^-1 M``, ``M`` the free columns' products with the
        derivatives, both off the basis), and ``D^T R = D^T Y - M^T C``."""
        C, ZZ, ZY, G, norms = state
        k = 2 * free.size
        M = ZZ[:k, k:]
        gram = ZZ[k:, k:] - M.T @ (np.linalg.pinv(G, rcond=1e-10, hermitian=True)
                                   @ (M / norms[:, None]) / norms[:, None])
        dr = ZY[k:] - M.T @ C
        Cx = _coefficient_rows(free, C)
        W = gram * (Cx @ Cx.T)
        u = np.sum(Cx * dr, axis=1)
        n = Cx.shape[0] // 2
        return W.reshape(n, 2, n, 2).sum(axis=(1, 3)), -u.reshape(n, 2).sum(axis=1)


def _block_sums(X: np.ndarray) -> np.ndarray:
    """Rows of a stacked ``(2N, k)`` array summed per line (real and imaginary rows) and
    then per block of :data:`CLUSTER_LINES` lines (the last block padded)."""
    n = X.shape[0] // 2
    per_line = X[:n] + X[n:]
    pad = (-n) % CLUSTER_LINES
    per_line = np.vstack([per_line, np.zeros((pad, X.shape[1]))])
    return per_line.reshape(-1, CLUSTER_LINES, X.shape[1]).sum(axis=1)


def _small_sample(clusters: float) -> float:
    """Variance factor of a clustered sandwich from ``clusters`` effective clusters: the
    usual ``G / (G - 1)``, and ``(t_{0.975, G-1} / 1.96)^2`` so that the reported
    ``estimate +- 1.96 std`` is the t interval with ``G - 1`` degrees of freedom."""
    from scipy.special import stdtrit  # the t quantile (scipy.stats costs 0.6 s to import)

    g = max(float(clusters), 2.0)
    return g / (g - 1.0) * (float(stdtrit(g - 1.0, 0.975)) / 1.959963984540054) ** 2


def _whitened(
    omega: np.ndarray, H: np.ndarray, variance: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``s = i omega``, the square root of the line weights, the whitened data ``(N, E)``
    of the separable noise model and its entry variances ``(E,)``."""
    N = H.shape[0]
    line_var, entry_var = separable_weights(np.asarray(variance, float).reshape(N, -1))
    sw = 1.0 / np.sqrt(line_var)
    Y = sw[:, None] * np.asarray(H).reshape(N, -1) / np.sqrt(entry_var)[None, :]
    return 1j * np.asarray(omega, dtype=float), sw, Y, entry_var


def _reach(start: np.ndarray, others: np.ndarray) -> np.ndarray:
    """How far each starting pole may move: :data:`MAX_MOVE` half-bandwidths, or up to
    :data:`TERRITORY` of the distance to the nearest other pole (the other starts and the
    fixed poles, conjugates included) when that is further."""
    half = np.maximum(np.abs(start.real), 1e-12)
    pool = np.concatenate([start, others, np.conj(others)])
    d = np.abs(start[:, None] - pool[None, :])
    d[np.arange(start.size), np.arange(start.size)] = np.inf
    gap = d.min(axis=1)
    gap[~np.isfinite(gap)] = 0.0  # a lone pole (no neighbour at all): the fixed limit
    return np.maximum(MAX_MOVE * half, TERRITORY * gap)


def nearest_starts(got: np.ndarray, start: np.ndarray) -> np.ndarray:
    """Which of the fitted poles ``got`` each of ``start`` became, were they exchanged: an
    index into ``got`` per start, one to one, the closest pair first (distance in the
    wider pole's half-bandwidth, :func:`separation`); the identity where every start is
    nearest its own fitted pole, or where a distance is not finite (a pole that is not, or
    two undamped ones).

    :func:`_fit_holding_strays` takes this pairing only where it leaves fewer poles
    judged strayed than the fit's own order does (:func:`_arranged`).
    """
    start = np.asarray(start, dtype=complex).ravel()
    d = separation(np.concatenate([start, np.asarray(got, dtype=complex).ravel()]))
    d = d[: start.size, start.size:]  # (start, got)
    out = np.arange(start.size)
    if start.size < 2 or not np.all(np.isfinite(d)) or np.all(np.argmin(d, axis=1) == out):
        return out
    for _ in range(start.size):
        j, i = np.unravel_index(int(np.argmin(d)), d.shape)
        out[j] = i
        d[j, :] = np.inf
        d[:, i] = np.inf
    return out


def _strayed(got: np.ndarray, start: np.ndarray, limit: np.ndarray,
             width: bool = True) -> np.ndarray:
    """Which fitted poles ``got`` have left what a refinement of ``start`` may do: beyond
    ``limit`` (:func:`_reach`), unstable, and (``width``) a half-bandwidth changed by more
    than :data:`MAX_DAMPING_CHANGE` times. A pole that is not finite has strayed."""
    with np.errstate(invalid="ignore"):
        bad = ~(np.abs(got - start) <= limit) | ~(got.real < 0) | ~(got.imag > 0)
        if width:
            ratio = np.abs(got.real) / np.maximum(np.abs(start.real), 1e-12)
            bad |= ~((ratio <= MAX_DAMPING_CHANGE) & (ratio >= 1.0 / MAX_DAMPING_CHANGE))
    return bad


def _arranged(got: np.ndarray, start: np.ndarray, limit: np.ndarray,
              width: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The fitted poles in the order of the starts they are judged by, and which of them
    strayed (:func:`_strayed`, judged so).

    A joint fit's poles are unordered (the model is their sum): a pole may take its
    neighbour's resonance while the neighbour moves off (seed 2381 f_05, a 35 x 3 dense
    grid: a companion 0.09 Hz above a mode of SNR 32 000 took the mode's resonance and the
    mode's pole narrowed 4 times beside it, so the mode kept its bootstrap statistics).
    The starts' pairing with the poles nearest them (:func:`nearest_starts`) is taken
    unless it leaves more strays (:func:`_strayed`) than the fit's order (a narrow mode
    beside a broad companion, each within its own reach, though the companion's start lies
    nearer the mode's pole: paired nearest first, both were held). Where the two orders
    leave as many, the nearest pairing stands: in that grid's fit the exchange left one
    stray either way, the mode's own pole or the companion.
    """
    bad = _strayed(got, start, limit, width)
    perm = nearest_starts(got, start)
    if np.array_equal(perm, np.arange(perm.size)):
        return got, bad
    moved = got[perm]
    bad_moved = _strayed(moved, start, limit, width)
    return (moved, bad_moved) if bad_moved.sum() <= bad.sum() else (got, bad)


def _fit_holding_strays(
    s: np.ndarray, sw: np.ndarray, Y: np.ndarray, free0: np.ndarray, fixed: np.ndarray,
    max_iterations: int, pmap: Callable, initial: np.ndarray, held: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, int]:
    """The Gauss-Newton fit of ``free0`` (whitened data ``Y`` at ``s``, line weights' root
    ``sw``, ``fixed`` poles held), refitted with each pole that strayed held at its start
    (one more each time; see :func:`refine_poles`). The iterations begin at ``initial``
    (``free0``'s shape); reach and damping change are judged from ``free0``. The poles
    ``held`` (a mask) are held at their starts from the first fit on.

    Returns
    -------
    poles : ndarray, shape (m,)
        The fitted poles; the start where the pole strayed.
    ok : ndarray of bool, shape (m,)
        Whether each pole was fitted.
    iterations : int
        Iterations of the last fit.
    """
    m = free0.size
    reach = _reach(free0, fixed)
    ok = ~np.asarray(held, bool)
    poles, it = free0.copy(), 0
    current = np.array(initial, dtype=complex)
    if not ok.any():
        return poles, ok, it
    for _ in range(m):
        idx = np.flatnonzero(ok)
        prob = _Problem.make(s, sw, Y, np.concatenate([free0[~ok], fixed]), pmap)
        start, limit = free0[idx], reach[idx]

        def left(got: np.ndarray, start: np.ndarray = start,
                 limit: np.ndarray = limit) -> np.ndarray:
            # out of reach or unstable: no later step brings a pole back from there (each
            # start judged by the pole it became, _arranged)
            return _arranged(got, start, limit, False)[1]

        got, it, _ = _gauss_newton(prob, current[idx], max_iterations, left)
        # the half-bandwidth is judged at the end only: from a start off its resonance a
        # pole first widens to reach it (4.8 times, 5 half-bandwidths off), then narrows
        got, bad = _arranged(got, start, limit)
        ok[idx[bad]] = False
        if not bad.any():
            poles[idx] = got
            break
        current[idx] = got  # the others go on from where they were
        if not ok.any():
            break
    return poles, ok, it


def refine_poles(
    omega: np.ndarray,
    H: np.ndarray,
    variance: np.ndarray,
    free: np.ndarray,
    fixed: np.ndarray,
    max_iterations: int = MAX_ITERATIONS,
    jobs: int | None = 1,
    initial: np.ndarray | None = None,
    held: np.ndarray | None = None,
) -> PoleRefinement:
    """Refine the poles ``free`` of a pole-residue model of ``H`` by weighted least squares.

    Parameters
    ----------
    omega : ndarray, shape (N,)
        Lines (rad/s), positive and increasing.
    H : ndarray, shape (N, ny, nu)
        FRF at those lines (data as measured: any exponential window's effect included).
    variance : ndarray, shape (N, ny, nu)
        Noise variance of each line and entry (``E |noise|^2``), positive.
    free : ndarray, shape (m,)
        Starting poles to refine (rad/s, ``Im > 0``), e.g. the subspace estimate's.
    fixed : ndarray, shape (q,)
        Other poles of the model, kept fixed: a pole pair by its pole with ``Im > 0`` (its
        conjugate, if given too, is ignored), a real pole as itself.
    max_iterations : int
        Gauss-Newton iterations at most, per fit.
    jobs : int or None
        Worker threads for the fit's and the covariance's sums
        (:func:`automodal.core.parallel.worker_count`); the result does not depend on it.
    initial : ndarray, shape (m,), optional
        Where the iterations begin, when not at ``free`` (a fit made again after a change
        of the model begins at the previous fit's poles). Reach and damping change are
        still judged from ``free``, and a pole not refined is left at ``free``.
    held : ndarray of bool, shape (m,), optional
        Poles held at ``free`` from the start, as if they had strayed (say, the poles a
        previous fit held, :attr:`PoleRefinement.held`). They are not refined.

    Returns
    -------
    PoleRefinement
        A pole that moved further than its reach (:func:`_reach`), turned unstable, whose
        half-bandwidth changed by more than :data:`MAX_DAMPING_CHANGE` or whose information
        is singular is not refined (the fit goes on with it fixed at its start).

    Notes
    -----
    Noise-free data of a model whose poles are all among ``free`` and ``fixed`` are fitted
    exactly: the starting poles are then the optimum and are returned unchanged (up to
    rounding).
    """
    omega = np.asarray(omega, dtype=float)
    H = np.asarray(H)
    N = H.shape[0]
    free0 = np.asarray(free, dtype=complex).ravel()
    fixed = np.asarray(fixed, dtype=complex).ravel()
    fixed = fixed[fixed.imag >= 0]
    m = free0.size
    initial = free0 if initial is None else np.asarray(initial, dtype=complex).ravel()
    held = np.zeros(m, bool) if held is None else np.asarray(held, bool).ravel()
    if initial.shape != free0.shape or held.shape != free0.shape:
        raise ValueError(f"initial and held must have one entry per free pole ({m})")
    nan_cov = np.full((m, 2, 2), np.nan)
    if m == 0 or N < 2 * (2 * m + fixed.size + 1):
        return PoleRefinement(free0.copy(), nan_cov, np.full(m, np.nan), np.zeros(m, bool), 0,
                              np.full((m, *H.shape[1:]), np.nan, dtype=complex),
                              np.full(m, np.nan), np.full((m, *H.shape[1:]), np.nan),
                              np.ones(m, bool))
    s, sw, Y, entry_var = _whitened(omega, H, variance)
    # the halves of the rows' sums on two workers where an iteration's work pays for them
    work = 8.0 * N * m * (fixed.size + 2 * m + Y.shape[1])
    with freeing_map(jobs if work >= PARALLEL_MIN_FLOPS else 1, 2) as (_, pmap):
        poles, ok, it = _fit_holding_strays(s, sw, Y, free0, fixed, max_iterations, pmap,
                                            initial, held)
        fit_held = ~ok
        idx = np.flatnonzero(ok)
        cov, disp = nan_cov, np.full(m, np.nan)
        if idx.size:
            # the held pole pairs were estimated too (by the subspace method): their
            # uncertainty is the refined poles' own wherever the two are correlated; the
            # band's resonances, that is: the rest is background (see _in_band)
            others = np.concatenate([free0[~ok], fixed])
            pair = others.imag > 1e-9 * np.maximum(np.abs(others), 1e-300)
            pair[pair] = _in_band(others[pair], omega)
            cov[idx], disp[idx] = _covariance(_Problem.make(s, sw, Y, others[~pair], pmap),
                                              poles[idx], others[pair],
                                              separable_ratio(variance), jobs)
    singular = np.zeros(m, bool)
    singular[idx] = ~np.all(np.isfinite(cov[idx]), axis=(1, 2)) | (cov[idx, 0, 0] < 0) | (
        cov[idx, 1, 1] < 0)
    ok[singular] = False
    poles[singular] = free0[singular]
    cov[singular] = np.nan
    residues, residue_var, entry_rv = _residues(
        s, sw, Y, entry_var, poles, free0, fixed, ok,
        np.asarray(variance, float).reshape(N, -1))
    return PoleRefinement(poles=poles, covariance=cov, dispersion=disp, refined=ok,
                          iterations=it, residues=residues.reshape(m, *H.shape[1:]),
                          residue_variance=residue_var,
                          entry_variance=entry_rv.reshape(m, *H.shape[1:]), held=fit_held)


def _in_band(pairs: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Which held pole ``pairs`` are resonances of the band ``omega`` (rad/s), and so
    nuisance parameters of the covariance (:func:`_covariance`): stable, their
    half-bandwidth ``|Re|`` under the band's width and their half-power interval
    ``Im +- |Re|`` reaching into the band.

    The others are background, as the residual terms are: their locations are not
    resolved by the band's lines, and the model's columns of such poles (an over-sized
    model's broad poles) are nearly those of the residual terms. Their residues in a joint
    fit then cancel at sizes up to 1e12 times the modes', so their derivative columns,
    and any interval that projects them out, were set by rounding: perturbing the held
    poles of a dense band by 1e-15 (relative) moved standard deviations by up to 60 %
    (seed 281, f_14), against 2e-5 once those poles are held as background.
    """
    half = -pairs.real
    width = omega[-1] - omega[0]
    return ((half > 0) & (half < width) & (pairs.imag + half > omega[0])
            & (pairs.imag - half < omega[-1]))


def _residues(
    s: np.ndarray, sw: np.ndarray, Y: np.ndarray, entry_var: np.ndarray, poles: np.ndarray,
    start: np.ndarray, fixed: np.ndarray, ok: np.ndarray, variance: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Residues ``(m, E)`` (data units) of the refined poles ``poles[ok]`` with the others
    (``start[~ok]`` and ``fixed``) in the basis, the variance of each pole's whitened
    residues under the separable noise model, and the variance ``(m, E)`` of each residue
    entry under the noise ``variance`` ``(N, E)`` as it is.

    The whitened data have unit complex variance under the separable model, so the real
    coefficients have ``(P^T P)^-1 / 2`` (``P`` the pole's stacked columns off the rest of
    the basis) and a residue the sum of its two. The coefficients are ``G y`` with
    ``G = (P^T P)^-1 P^T`` (``P`` is orthogonal to the rest of the basis), so under the
    full variance each entry's residue has ``sum_k G_k^2 w_k V_ke / 2`` over the stacked
    rows ``k`` (``w_k`` the line weight, ``V_ke / 2`` the variance of a real or imaginary
    part)."""
    m = poles.size
    residues = np.full((m, Y.shape[1]), np.nan, dtype=complex)
    whitened_var = np.full(m, np.nan)
    entry_rv = np.full((m, Y.shape[1]), np.nan)
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return residues, whitened_var, entry_rv
    prob = _Problem.make(s, sw, Y, np.concatenate([start[~ok], fixed]))
    C = _fit(prob, poles[idx])[1]
    residues[idx] = (C[0::2] + 1j * C[1::2]) * np.sqrt(entry_var)[None, :]
    P = prob.off_fixed(_stack(sw[:, None] * _pair_columns(s, poles[idx])))
    inv = np.linalg.pinv(P.T @ P)
    cov = 0.5 * np.diag(inv)
    whitened_var[idx] = cov[0::2] + cov[1::2]
    G2 = (inv @ P.T) ** 2
    G2 = G2[0::2] + G2[1::2]  # a residue's real and imaginary coefficient
    n = s.size
    entry_rv[idx] = 0.5 * (((G2[:, :n] + G2[:, n:]) * (sw**2)[None, :]) @ variance)
    return residues, whitened_var, entry_rv


def _covariance(
    prob: _Problem, poles: np.ndarray, nuisance: np.ndarray | None = None,
    ratio: np.ndarray | None = None, jobs: int | None = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """Covariance ``(m, 2, 2)`` of ``(Re, Im)`` of fitted ``poles`` and their dispersion
    (see :class:`PoleRefinement`).

    ``nuisance`` are poles of the model that ``prob`` does not hold fixed (its fixed part
    lacks them) although they were not refitted: their own uncertainty is accounted for
    by the efficient score and information of ``poles`` (the Schur complement).
    ``ratio`` ``(N, E)`` is the noise model's variance over the separable one the fit
    weighs with (:func:`separable_ratio`): the model's covariance is then that of a
    weighted least-squares estimate under the noise model, ``A^-1 B A^-1`` with ``B``
    the scores' covariance (:func:`_weighted_information`), which is ``A^-1`` when the
    variance is separable."""
    m = poles.size
    nuisance = np.zeros(0, complex) if nuisance is None else nuisance
    both = np.concatenate([poles, nuisance])
    cost, C, R, Qp = _fit(prob, both)
    parts = _jacobian_parts(prob, both, C, Qp)
    normal, _ = _normal_equations(prob, parts, R)
    # leverage of the linear part per stacked row; residuals corrected for it
    leverage = np.clip(np.sum(prob.Qf**2, axis=1) + np.sum(Qp**2, axis=1), 0.0, 1.0 - 1e-9)
    Rc = R / np.sqrt(1.0 - leverage)[:, None]
    PD, Cx = np.vstack(parts[1]), parts[2]
    # clustered sandwich: the scores of each block of CLUSTER_LINES lines over all their
    # entries (real and imaginary rows together), so errors correlated across the entries
    # of a line (an H1 estimate's shared force noise) or between neighbouring lines (a
    # window's leakage), or not matching the separable model, count as they are
    score = -(PD * (Rc @ Cx.T))  # (2N, 4M): per row, each derivative column's share
    score = _block_sums(score.reshape(score.shape[0], -1, 2).sum(axis=2))  # (blocks, 2M)
    k = 2 * m
    if nuisance.size:  # efficient score and information of the poles of interest
        T = _nuisance_regression(normal, k)
        normal = normal[:k, :k] - T @ normal[k:, :k]
        score = score[:, :k] - score[:, k:] @ T.T
    try:
        info_inv = np.linalg.inv(normal)
    except np.linalg.LinAlgError:
        info_inv = np.full_like(normal, np.nan)
    # each complex whitened residual has E|e|^2 = 1 (times ratio): real and imaginary
    # parts 1/2 each
    cov_model = 0.5 * info_inv
    # ratio within 1 +- SEPARABLE_TOLERANCE bounds B between those multiples of A
    if ratio is not None and np.max(np.abs(ratio - 1.0)) > SEPARABLE_TOLERANCE:
        B = _weighted_information(PD, Cx, ratio, k, T if nuisance.size else None, jobs)
        cov_model = 0.5 * info_inv @ B @ info_inv
    cov_free = np.stack([cov_model[2 * i: 2 * i + 2, 2 * i: 2 * i + 2] for i in range(m)])
    robust = info_inv @ (score.T @ score) @ info_inv
    # where each pole's information lies, per block: its effective number of blocks (Kish)
    # sets a small-sample correction of the sandwich
    info = _block_sums(PD[:, : 4 * m] ** 2 * np.sum(Cx[: 4 * m] ** 2, axis=1)[None, :])
    info = info.reshape(info.shape[0], -1, 4).sum(axis=2)  # per pole, (blocks, m)
    disp = np.full(m, np.nan)
    cov = np.empty((m, 2, 2))
    for j in range(m):
        block = slice(2 * j, 2 * j + 2)
        model = cov_free[j]
        g = float(np.sum(info[:, j]) ** 2 / max(np.sum(info[:, j] ** 2), 1e-300))
        sand = robust[block, block] * _small_sample(g)
        # the larger of the model's and the data's covariance: the sandwich alone is noisy
        # when a sharp resonance spreads its information over a few lines
        disp[j] = float(np.trace(sand) / np.trace(model)) if np.trace(model) > 0 else np.nan
        cov[j] = sand if np.isfinite(disp[j]) and disp[j] > 1.0 else model
    return cov, disp


def _nuisance_regression(normal: np.ndarray, k: int) -> np.ndarray:
    """``N_fn N_nn^+``: the regression of the first ``k`` parameters' information on the
    others' (the nuisance parameters) in the Gauss-Newton matrix ``normal``.

    ``N_nn`` is scaled to a unit diagonal first, so the pseudo-inverse's cut sees columns
    that depend on each other, not the sizes of the residues behind them (their
    information spans ten decades in a dense band); where ``N_nn`` is singular, the
    result is still a generalized inverse's, and the Schur complement the same."""
    d = np.sqrt(np.diag(normal)[k:])
    d = np.where(d > 0, d, 1.0)
    scaled = np.linalg.pinv(normal[k:, k:] / np.outer(d, d), rcond=1e-10, hermitian=True)
    return (normal[:k, k:] / d[None, :]) @ scaled / d[None, :]


def _weighted_information(
    PD: np.ndarray, Cx: np.ndarray, ratio: np.ndarray, k: int, T: np.ndarray | None,
    jobs: int | None = 1,
) -> np.ndarray:
    """``sum_e J_e^T diag(ratio_e) J_e`` over the entries ``e``: the whitened scores'
    covariance (twice it) when entry ``e`` at line ``k`` has noise variance
    ``ratio[k, e]`` times the separable one.

    ``J_e`` is entry ``e``'s Jacobian of the first ``k`` parameters, efficient when ``T``
    (the nuisance parameters' regression, see :func:`_covariance`) is given: ``J_f - J_n
    T^T``. ``PD`` (stacked) and ``Cx`` are as from :func:`_jacobian_parts`: parameter ``t``
    owns columns ``2t`` and ``2t + 1`` of ``PD``, so every parameter's Jacobian of entry
    ``e`` is ``PD[:, 2t] Cx[2t, e] + PD[:, 2t + 1] Cx[2t + 1, e]``, formed for a chunk of
    entries at once (a product over the pair); the nuisance parameters' share is one
    matrix product, and the sum of ``J^T diag J`` a symmetric rank-k update. (One product
    of ``PD`` with a block matrix per entry instead took 2.6 times as long: 1.26 s for a
    38 x 3 dense grid's sub-band, seed 459 f_17, with 40 free and 19 nuisance poles.)
    The entries are shared among ``jobs`` worker threads in chunks fixed by the sizes,
    summed in order."""
    n2, a4 = PD.shape
    E = Cx.shape[1]
    n_all = a4 // 2
    rho = np.sqrt(np.concatenate([ratio, ratio], axis=0))  # stacked rows: real, imaginary
    step = max(1, int(4e6 // max(n2 * n_all, 1)))  # entries per chunk: fixed by the sizes
    chunks = [slice(lo, min(E, lo + step)) for lo in range(0, E, step)]
    pairs = np.ascontiguousarray(PD.reshape(n2, n_all, 2).transpose(1, 0, 2))  # (t, n2, 2)
    Cp = Cx.reshape(n_all, 2, E)

    def part(sl: slice) -> np.ndarray:
        J = pairs @ Cp[:, :, sl]  # (n_all, n2, e): every parameter's Jacobian per entry
        J = J.reshape(n_all, -1)
        W = J if T is None else J[:k] - T @ J[k:]
        W = W * rho[:, sl].reshape(1, -1)
        # numpy's product of an array with its own transpose is BLAS's symmetric rank-k
        # update, with the GIL released; scipy's dsyrk wrapper holds it, and two workers
        # took as long as one (session 47). The numbers are the same to the bit.
        return W @ W.T

    with freeing_map(jobs, len(chunks), 2.0 * n2 * E * k * (n_all + k)) as (_, pmap):
        parts = list(pmap(part, chunks))
    return np.sum(parts, axis=0)  # in chunk order: the same whatever the workers


def _wald_and_local(
    s: np.ndarray, sw: np.ndarray, Y: np.ndarray, poles: np.ndarray, fixed: np.ndarray,
    ratio: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per pole of ``poles``: the whitened cost its residues remove with everything else
    in the model (the Wald statistic ``beta^T V^{-1} beta`` summed over entries), the
    model's residual over its degrees of freedom on the lines within
    :data:`LOCAL_HALF_BANDWIDTHS` half-bandwidths of the pole (the local dispersion, at
    least 1: the scale of the tests' statistics), that residual over what the noise model
    expects of it there (its excess), and the degrees of freedom of the chi-square law that
    excess follows under the noise model.

    The data are whitened with the separable model of the noise variance; ``ratio``
    ``(N, E)`` (:func:`separable_ratio`, 1 where omitted) is the noise model's variance over
    it, so a whitened residual of line ``k`` and entry ``e`` expects ``ratio[k, e]`` times
    its share ``1 - leverage`` of a unit variance. Where the ratio varies (noise
    proportional to ``|H|``, an H1 estimate's), the residual's sum is a weighted sum of
    chi-squares, taken as a scaled chi-square with its mean and variance (Satterthwaite):
    ``nu = 2 M^2 / V`` degrees of freedom. With a unit ratio and no leverage, ``nu`` is
    twice the local lines' entries, each whitened complex residual counting one."""
    N = Y.shape[0]
    Ys = _stack(Y)
    X = _stack(sw[:, None] * np.concatenate(
        [_pair_columns(s, poles), _fixed_columns(s, fixed)], axis=1))
    norms = np.linalg.norm(X, axis=0)
    X = X / np.where(norms > 0, norms, 1.0)[None, :]
    Q, R = _qr(X)
    QY = Q.T @ Ys
    Rinv = np.linalg.pinv(R)
    beta = Rinv @ QY
    wald = np.empty(poles.size)
    for j in range(poles.size):
        J = slice(2 * j, 2 * j + 2)
        b = beta[J]
        wald[j] = float(np.sum(b * (np.linalg.pinv(Rinv[J] @ Rinv[J].T) @ b)))
    # a whitened complex residual has E|e|^2 = 1: a stacked real row expects
    # (1 - leverage) / 2 per entry
    resid = Ys - Q @ QY
    row_cost = np.sum(resid * resid, axis=1)
    kept = 1.0 - np.sum(Q * Q, axis=1)  # each stacked row's share left by the fit
    row_dof = 0.5 * kept * Ys.shape[1]
    line_cost = row_cost[:N] + row_cost[N:]
    line_dof = row_dof[:N] + row_dof[N:]
    r = np.ones_like(Y, dtype=float) if ratio is None else np.asarray(ratio, float)
    # a real or imaginary part of a whitened residual: variance ratio (1 - leverage) / 2,
    # so its square has mean that and variance twice its square
    r1, r2 = r.sum(axis=1), (r * r).sum(axis=1)
    line_mean = 0.5 * (kept[:N] + kept[N:]) * r1
    line_var = 0.5 * (kept[:N] ** 2 + kept[N:] ** 2) * r2
    local = np.empty(poles.size)
    excess = np.empty(poles.size)
    nu = np.empty(poles.size)
    for j, lam in enumerate(poles):
        dist = np.abs(s.imag - lam.imag)
        near = dist <= LOCAL_HALF_BANDWIDTHS * max(abs(lam.real), 1e-12)
        if near.sum() < MIN_LOCAL_LINES:
            near = np.argsort(dist)[:MIN_LOCAL_LINES]
        cost = float(np.sum(line_cost[near]))
        local[j] = cost / max(float(np.sum(line_dof[near])), 1e-12)
        mean = max(float(np.sum(line_mean[near])), 1e-12)
        excess[j] = cost / mean
        nu[j] = 2.0 * mean**2 / max(float(np.sum(line_var[near])), 1e-300)
    return wald, np.maximum(local, 1.0), excess, nu


def residue_wald(fit: PoleRefinement) -> np.ndarray:
    """Each pole's Wald statistic for its residues, ``2 sum_e |R_e|^2 / var(R_e)`` over the
    FRF entries ``e`` (:attr:`PoleRefinement.entry_variance`, each entry's error variance
    under the noise variance as given).

    The residues are linear in the data, and the entries' errors independent, so where
    the data hold no mode at a fixed pole the statistic is a chi-square with ``2 E``
    degrees of freedom (``E`` complex residues); fitting the pole to the noise adds about
    its two parameters. A mode raises it by about twice its SNR^2 (its whitened energy
    ``sum |H_mode|^2 / var``), less what the other poles' terms share. NaN where the pole
    was not refined.

    Returns
    -------
    ndarray, shape (m,)
    """
    with np.errstate(invalid="ignore", divide="ignore"):
        w = 2.0 * np.sum(np.abs(fit.residues) ** 2 / fit.entry_variance, axis=(1, 2))
    return np.where(fit.refined, w, np.nan)


def residue_shapes(
    residues: np.ndarray, variance: np.ndarray, residue_variance: np.ndarray,
    entry_variance: np.ndarray | None = None,
) -> np.ndarray:
    """Mode shapes from the residue matrices of a fit, where each is one mode's.

    A mode's residue is rank one, ``R_r = phi_r psi_r^T`` (output shape times input
    participation); the fit's estimate adds its own error, of variance
    ``residue_variance`` per whitened entry. Whitened (each output and input divided by
    the square root of its factor of the entries' separable noise variance,
    :func:`separable_weights`, so that the rank-one structure is kept), a residue matrix
    whose largest singular value stands out of that error (above :data:`RESIDUE_RANK_EDGE`
    times the largest an ``ny x nu`` error matrix gives) and whose second does not (against
    an ``(ny - 1) x (nu - 1)`` one) is one mode's: its shape is the dominant left singular
    vector, the whitening of the outputs undone. Otherwise (a pole whose terms are nearly
    collinear with a neighbour's, or that stands for two near-coincident modes) the shape
    is NaN, and the caller keeps another estimate.

    With ``entry_variance`` (each entry's own error variance, which the separable model
    does not give where the noise follows ``|H|``), the singular vector is taken of the
    residue shrunk toward zero entry by entry (:func:`automodal.core.shrinkage.shrunk`):
    an entry whose error exceeds the mode's response in the other entries no longer sets
    the shape (a channel that another mode dominates at this mode's lines, under noise
    proportional to it; seed 419, f_24: MAC 0.02 and 0.19 against the true shapes without
    it, 0.99 with it).

    Parameters
    ----------
    residues : ndarray, shape (m, ny, nu), complex
        Residue matrices (NaN for a pole not refined).
    variance : ndarray, shape (N, ny, nu)
        Noise variance of the FRF entries.
    residue_variance : ndarray, shape (m,)
        :attr:`PoleRefinement.residue_variance`.
    entry_variance : ndarray, shape (m, ny, nu), optional
        :attr:`PoleRefinement.entry_variance`.

    Returns
    -------
    ndarray, shape (ny, m), complex
        One shape per column (unnormalised), NaN where the residue is not one mode's.
    """
    R = np.asarray(residues, dtype=complex)
    m, ny, nu = R.shape
    V = np.asarray(variance, float)
    whiten, unwhiten = residue_whitening(
        separable_weights(V.reshape(V.shape[0], -1))[1], (ny, nu))
    Rw = R * whiten[None]
    shapes = np.full((ny, m), np.nan, dtype=complex)
    rv = np.asarray(residue_variance, float)
    # a negative variance (the rounding of a near-singular pseudo-inverse's diagonal) is
    # no variance: that residue's shape is left unknown, as for a NaN
    sigma = np.sqrt(np.where(rv >= 0, rv, np.nan))
    ok = np.all(np.isfinite(Rw), axis=(1, 2)) & np.isfinite(sigma)
    if not ok.any():
        return shapes
    U, sv, _ = np.linalg.svd(Rw[ok], full_matrices=False)
    first = sv[:, 0] > RESIDUE_RANK_EDGE * sigma[ok] * (np.sqrt(ny) + np.sqrt(nu))
    second = sv[:, 1] if sv.shape[1] > 1 else np.zeros(sv.shape[0])
    second_edge = RESIDUE_RANK_EDGE * sigma[ok] * (np.sqrt(ny - 1) + np.sqrt(nu - 1))
    one = first & (second <= second_edge)
    vectors = U[one, :, 0]
    if entry_variance is not None:
        for i, r in enumerate(np.flatnonzero(ok)[one]):
            Rs = shrunk(R[r], entry_variance[r])
            vectors[i] = (np.linalg.svd(Rs * whiten, full_matrices=False)[0][:, 0]
                          if np.any(Rs != 0) else np.nan)
    shapes[:, np.flatnonzero(ok)[one]] = (vectors * unwhiten[None, :]).T
    return shapes


def residue_whitening(
    entry_var: np.ndarray, shape: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """Factors that whiten a residue matrix and keep its rank.

    The entries' noise variances (``entry_var``, ``(E,)``, :func:`separable_weights`) are
    fitted as an output factor times an input factor (a two-way model of their logarithm);
    dividing each output and input by the square root of its factor gives the residue
    errors about equal variance while a rank-one matrix stays rank one.

    Returns
    -------
    whiten : ndarray, shape (ny, nu)
        To multiply a residue matrix by.
    unwhiten : ndarray, shape (ny,)
        To multiply a whitened left singular vector by, for a shape in the data's units.
    """
    ny, nu = shape
    entry = np.log(np.asarray(entry_var, float).reshape(ny, nu))
    a = np.mean(entry, axis=1)  # output factor of the entries' variance
    b = np.mean(entry - a[:, None], axis=0)  # and input factor
    return np.exp(-0.5 * a)[:, None] * np.exp(-0.5 * b)[None, :], np.exp(0.5 * a)


def rank_one_excess(
    C: np.ndarray, gram: np.ndarray, entry_var: np.ndarray, shape: tuple[int, int],
    iterations: int = 100,
) -> float:
    """How much a pole's whitened cost rises when its residues are made one mode's.

    One mode's residue matrix is ``phi psi^T`` (``ny x nu``, rank one). With the pole and
    the other columns fixed, the cost is quadratic in the pole's coefficients ``C``
    (``(2, E)``: the real and imaginary parts of each whitened residue, the columns of
    :func:`_pair_columns`) with the matrix ``gram`` (those two columns' Gram matrix off the
    others), so the rise is ``min sum_e d_e^T gram d_e`` over the rank-one residues, ``d_e``
    the change of entry ``e``'s coefficients. Taken here as ``gram``'s smaller eigenvalue
    ``mu`` times ``min sum_e |R_e - phi_o psi_i|^2 / c_e`` (``R_e`` the residue in the
    data's units, ``c_e = entry_var[e]``), which is below the rise: the weighted rank-one
    fit by alternating least squares, from the leading singular pair of the residue whitened
    by outputs and inputs (:func:`residue_whitening`; the exact minimum where the entries'
    variances are an output factor times an input factor).

    Parameters
    ----------
    C : ndarray, shape (2, E)
    gram : ndarray, shape (2, 2)
    entry_var : ndarray, shape (E,)
        Entry variances of the whitening (:func:`separable_weights`).
    shape : (ny, nu)
        The FRF's outputs and inputs, ``ny nu = E``.
    iterations : int
        Alternating steps at most (each lowers the sum; they stop when it changes by less
        than 1e-10 of itself).

    Returns
    -------
    float
    """
    ny, nu = shape
    if min(ny, nu) < 2:
        return 0.0
    var = np.asarray(entry_var, float)
    R = ((C[0] + 1j * C[1]) * np.sqrt(var)).reshape(ny, nu)
    w = (1.0 / var).reshape(ny, nu)
    whiten, _ = residue_whitening(var, shape)
    U, sv, Vh = np.linalg.svd(R * whiten)
    phi = U[:, 0] * sv[0] / whiten[:, 0]
    psi = Vh[0] * (whiten[0, 0] / whiten[0])  # whiten = a_o b_i: b_i undone here
    tiny = np.finfo(float).tiny
    cost = float(np.sum(w * np.abs(R - np.outer(phi, psi)) ** 2))
    for _ in range(iterations):
        phi = (w * R) @ psi.conj() / np.maximum(w @ np.abs(psi) ** 2, tiny)
        psi = (w * R).T @ phi.conj() / np.maximum(w.T @ np.abs(phi) ** 2, tiny)
        new = float(np.sum(w * np.abs(R - np.outer(phi, psi)) ** 2))
        done = cost - new <= 1e-10 * new
        cost = min(cost, new)
        if done:
            break
    mu = float(np.linalg.eigvalsh(0.5 * (gram + gram.T))[0])
    return max(mu, 0.0) * cost


@dataclass(frozen=True)
class PairVerdicts:
    """What :func:`pair_verdicts` found of each tested pole.

    Attributes
    ----------
    duplicate : ndarray of bool, shape (m,)
        The data do not need the pole beside a neighbour: one pole with one mode's residues
        fits the pair (a split resonance, or an over-sized model's second pole there); where
        the model misses the data about the pair by more than the noise, or the two poles
        started on two resonances (:attr:`carried`), one pole fits it (the residue's rank is
        not judged there).
    repeats : ndarray of int, shape (m,)
        For a pole whose pair one pole fits, but not with one mode's residues (a rank-one
        matrix; the residue there has a second direction the noise does not give): the
        other pole of the pair, whose resonance this one repeats (two modes sharing a
        pole, a repeated pair); -1 for every other pole.
    fits : ndarray of bool, shape (m,)
        Whether the model fits the data to the noise about each pole (its local residual,
        over what the noise model expects of it there, within what the noise alone gives at
        the test's level, times the noise model's accuracy
        :data:`automodal.core.noise.VARIANCE_ACCURACY`), for every pole; all True
        where :func:`pair_verdicts` tested nothing (no pair within reach, or too few lines).
    carried : ndarray of bool, shape (m,)
        The duplicates whose pair started on two resonances (``starts`` further apart than
        :data:`DUPLICATE_HALF_BANDWIDTHS` half-bandwidths): the fit carried the pole from
        its own resonance onto its partner's, and its start's mode is not judged.
    tested : ndarray of bool, shape (m,)
        The poles of at least one pair whose test was made. A pair within reach is not
        tested when either pole left as a duplicate or a repeat before its turn, nor when
        the lines are too few for any test.
    """

    duplicate: np.ndarray
    repeats: np.ndarray
    fits: np.ndarray
    carried: np.ndarray
    tested: np.ndarray

    @classmethod
    def untested(cls, m: int) -> PairVerdicts:
        """The verdicts of ``m`` poles of which no pair was tested."""
        return cls(np.zeros(m, bool), np.full(m, -1), np.ones(m, bool), np.zeros(m, bool),
                   np.zeros(m, bool))


def pair_verdicts(
    omega: np.ndarray,
    H: np.ndarray,
    variance: np.ndarray,
    poles: np.ndarray,
    fixed: np.ndarray,
    expendable: np.ndarray | None = None,
    jobs: int | None = 1,
    starts: np.ndarray | None = None,
    resolved: np.ndarray | None = None,
) -> PairVerdicts:
    """Which of the (refined) ``poles`` the data do not need beside a neighbour, and which
    repeat a neighbour's resonance.

    For each pair of ``poles`` closer than :data:`DUPLICATE_HALF_BANDWIDTHS` half-bandwidths
    (of the wider pole), closest pairs first, the weaker pole (the expendable one of a pair
    with one, else the smaller Wald statistic of its residues) is dropped and the other
    refitted alone, residues and pole: the whitened cost rises by ``delta``. If the pair
    were one pole, ``2 delta`` over the local dispersion would be chi-square with
    ``2 E + 2`` degrees of freedom (the weaker pole's ``E`` complex residues, tied to
    real-coefficient pairs, and its two pole parameters); when it stays below that law's
    ``1 - DUPLICATE_LEVEL`` quantile, one pole fits the pair. One mode's residues are a
    rank-one matrix, though: with at least two outputs and two inputs, the lone pole's
    residue is made rank one (:func:`rank_one_excess`), and if that raises the cost beyond
    the ``1 - DUPLICATE_LEVEL`` quantile of a chi-square with ``2 (ny - 1) (nu - 1)``
    degrees of freedom (over two, and the local dispersion), the pair is two modes sharing
    one pole (a repeated pair: the weaker pole :attr:`PairVerdicts.repeats` the other);
    otherwise the weaker pole is a duplicate and leaves the model for the next pairs. The
    rank test is made only where the model fits the data to the noise about both poles
    (each local residual, over what the noise model expects of it there, below the
    ``1 - DUPLICATE_LEVEL`` quantile the noise alone gives it, times the noise model's
    accuracy, :data:`automodal.core.noise.VARIANCE_ACCURACY`; see :func:`_wald_and_local`):
    beyond, a residue's second direction may be any structure the model misses.

    Without the rank test, the repeated pairs of nearly square grids (two modes 0.002 to
    0.004 Hz apart, half-bandwidths 0.3 to 0.7 Hz, two or three inputs) lost their second
    mode as a split resonance: 6 of the 18 clear modes (of 1018) missed on the seeds 977
    to 1013, of which this recovers 4 (the other two were found by a minority of the
    replicates). Two clusters of one rank each can be such a pair (seed 1097 f_04, a 23 x 3
    grid with a pair 0.0013 Hz apart at 31.1 Hz); two poles that the refinement brought
    together from two resonances are not (``starts``).

    Parameters
    ----------
    omega, H, variance
        As for :func:`refine_poles`.
    poles : ndarray, shape (m,)
        Poles to judge (``Im > 0``).
    fixed : ndarray, shape (q,)
        The model's other poles.
    expendable : ndarray of bool, shape (m,), optional
        Poles that give way to the others when a pair is one mode (say, an over-sized
        model's companions of the modes called physical), whatever their strength; each
        is then tested only against its nearest pole (the resonance it would split), and
        no other pair is tested.
    jobs : int or None
        Worker threads for the pairs' tests (:func:`automodal.core.parallel.worker_count`);
        the outcome does not depend on it.
    starts : ndarray, shape (m,), optional
        Where the fit of ``poles`` started (the subspace estimate's poles). Two poles may
        repeat one resonance only if they started on one, within
        :data:`DUPLICATE_HALF_BANDWIDTHS` half-bandwidths of each other: in a dense band a
        pole may pass its neighbours within its reach (seed 1049 f_17, a 23 x 3 dense grid:
        a mode's pole moved from 32.43 Hz to 31.81 Hz, 0.33 Hz from the pole at 31.48 Hz,
        and a false second mode of that one was reported). Such a pair is a mode and a
        duplicate, whatever the residue's rank.
    resolved : ndarray of bool, shape (m, m), optional
        Pairs whose starts the bootstrap replicates resolved as two frequencies (their
        clusters' mean frequencies further apart than 1.96 times the standard deviation of
        their difference, see :func:`automodal.core.summary.refine_physical_modes`): such
        a pair is two poles, not two modes of one, and is a mode and a duplicate when one
        pole fits it, whatever the residue's rank. Measured where the rank test first ran
        on noise proportional to ``|H|`` (seeds 1381, 1423, 1433): the repeated pairs' two
        clusters were 0.6-0.9 standard deviations apart (0.007 half-bandwidths), while a
        mode and a neighbour's leakage on its pole were 4.9 and 13.5 apart (1423 f_02,
        1433 f_23: 1.0 and 0.57 half-bandwidths), reported as two modes of one pole
        without it.

    Returns
    -------
    PairVerdicts
    """
    from scipy.special import chdtri  # chi-square quantile (scipy.stats: 0.6 s import)

    poles = np.asarray(poles, dtype=complex).ravel()
    fixed = np.asarray(fixed, dtype=complex).ravel()
    m = poles.size
    half = np.abs(poles.real)
    sep = separation(poles)
    start = poles if starts is None else np.asarray(starts, dtype=complex).ravel()
    one_start = within_reach(start)
    two_frequencies = (np.zeros((m, m), bool) if resolved is None
                       else np.asarray(resolved, bool).reshape(m, m))
    pairs = [(sep[a, b], a, b) for a in range(m) for b in range(a + 1, m)
             if sep[a, b] < DUPLICATE_HALF_BANDWIDTHS]
    if expendable is not None:  # an expendable pole is a split of its nearest resonance
        nearest = {int(e): min((p for p in pairs if e in p[1:]), default=None)
                   for e in np.flatnonzero(expendable)}
        pairs = list({p for p in nearest.values() if p is not None})
    if not pairs:
        return PairVerdicts.untested(m)
    s, sw, Y, entry_var = _whitened(omega, H, variance)
    if Y.shape[0] < 2 * (2 * m + fixed.size + len(RESIDUAL_POWERS)):
        return PairVerdicts.untested(m)
    dup = np.zeros(m, bool)
    repeats = np.full(m, -1)
    carried = np.zeros(m, bool)  # duplicates only
    judged = np.zeros(m, bool)  # poles of a pair whose test was made
    wald, local, over_noise, local_nu = _wald_and_local(s, sw, Y, poles, fixed,
                                                        separable_ratio(variance))
    threshold = float(chdtri(2 * Y.shape[1] + 2, DUPLICATE_LEVEL))
    shape = np.shape(H)[1:3] if np.ndim(H) == 3 else (Y.shape[1], 1)
    # a rank-one residue's excess of the free one's cost: chi-square with 2 (ny-1) (nu-1)
    # degrees of freedom over 2 (the rank-one matrices of ny x nu have ny + nu - 1 complex
    # parameters)
    rank_dof = 2 * (shape[0] - 1) * (shape[1] - 1)
    rank_threshold = float(chdtri(rank_dof, DUPLICATE_LEVEL)) if rank_dof > 0 else None
    # the largest excess of the local residual over the noise model's expectation that the
    # noise alone gives at that level (chi-square with nu degrees of freedom, over them),
    # with the noise model's own accuracy: the refined model leaves 7-13 % more than the
    # coherence law's variance all along the band of a family H1 file, isolated modes
    # included (seed 1097 f_04, 16 averages), and the local scatter alone barred every
    # pair there. The expectation is the noise model's, not the separable weighting's:
    # with noise proportional to |H| the weighting's residual is 2.2 times its unit
    # variance about a repeated pair where the model fits to the noise (seed 1381 f_01,
    # where the local residual and the noise model's ratio agreed within 3 % at every
    # pole), and measured against 1 no rank test was ever made on such data
    fit_limit = VARIANCE_ACCURACY * chdtri(local_nu, DUPLICATE_LEVEL) / local_nu
    base = _Problem.make(s, sw, Y, fixed)
    tested = base.off_fixed(_stack(sw[:, None] * _pair_columns(s, poles)))
    # each test's basis of the other tested poles: from one QR of all of them
    Qt, Rt = _qr(tested)
    QtY = Qt.T @ base.Yf
    every = _GramFit.make(base, Qt, QtY)  # every tested pole in the basis

    def weaker(a: int, b: int) -> tuple[int, int]:
        if expendable is not None and expendable[a] != expendable[b]:
            return (a, b) if expendable[a] else (b, a)
        return (a, b) if wald[a] < wald[b] else (b, a)

    def verdict(pair: tuple[int, int], out: np.ndarray) -> int:
        """0: two poles; 1: one mode; 2: two modes of one pole (the poles in ``out``
        having left the model)."""
        a, b = pair
        weak, strong = weaker(a, b)
        # the basis of the others: the fixed part once, the other tested poles off it
        keep = (~out) & (np.arange(m) != a) & (np.arange(m) != b)
        test = every.without(_left_out(Rt[:, np.repeat(keep, 2)]))
        both = test.fit(poles[[a, b]], derivatives=False)[0]
        # one pole when the lone pole's cost can come below this: the fit stops as soon as
        # it does (the answer is then known), else it runs to its end
        enough = both + 0.5 * threshold * local[weak]
        # the lone pole stays on the pair's resonance: where it may go beyond (a pole of
        # a band of log-spaced lines, most of them far below the modes, left for 286 Hz
        # from 7.08 Hz, fitting the low lines' misfit) the test would judge another model
        centre, reach = poles[strong], MAX_MOVE * max(half[a], half[b])

        def inside(p: np.ndarray) -> bool:
            return bool(abs(p[0] - centre) <= reach and p[0].real < 0 and p[0].imag > 0)

        lone, _, cost = _levenberg_marquardt(test.fit, test.normal_equations, poles[[strong]],
                                             MAX_ITERATIONS, enough=enough, inside=inside)
        if not cost < enough:
            return 0
        if rank_threshold is None or not one_start[a, b] or two_frequencies[a, b]:
            return 1
        if over_noise[a] > fit_limit[a] or over_noise[b] > fit_limit[b]:
            # the model misses the data there by more than the noise: a residue's second
            # direction may be any structure it misses (a dense grid's band whose local
            # dispersion was 200-1700 put five modes on one pole)
            return 1
        C, ZZ = test.fit(lone, derivatives=False)[1][:2]
        excess = rank_one_excess(C, ZZ[:2, :2], entry_var, shape)
        return 2 if excess >= 0.5 * rank_threshold * max(local[a], local[b]) else 1

    # closest pairs first, each test with the duplicates found before it out of the model;
    # a batch of the next pairs is tested at once on the workers, and the tests after the
    # first duplicate in it are made again without it, so the outcome is the sequential one
    pending = [(a, b) for _, a, b in sorted(pairs)]
    # each test: Gauss-Newton iterations on the rows against the fixed part and the others
    n_rows, n_entries = Y.shape
    work = len(pending) * MAX_ITERATIONS * 8.0 * n_rows * (fixed.size + 2 * m + n_entries)
    with freeing_map(jobs, len(pending), work) as (n_jobs, pmap):
        while pending:
            # a pole that repeats another's resonance leaves the model as a duplicate does:
            # its mode is in the other's residue (left in, the other pole absorbed it in a
            # test against a third pole within reach, and the pair lost its second mode)
            gone = dup | (repeats >= 0)
            pending = [(a, b) for a, b in pending if not (gone[a] or gone[b])]
            batch = pending[:n_jobs]
            pending = pending[n_jobs:]
            tests = pmap(verdict, batch, [gone] * len(batch))
            for k, v in enumerate(tests):
                judged[list(batch[k])] = True  # those after a duplicate are made again
                if v == 0:
                    continue
                weak, strong = weaker(*batch[k])
                if v == 1:
                    dup[weak] = True
                    carried[weak] = not one_start[weak, strong]
                else:
                    repeats[weak] = strong
                pending = batch[k + 1:] + pending
                break
    # a pole whose partner proved a duplicate is one too (the partner's resonance, which
    # held its mode, is a third pole's single mode)
    while True:
        orphan = (repeats >= 0) & dup[np.maximum(repeats, 0)]
        if not orphan.any():
            return PairVerdicts(dup, repeats, over_noise <= fit_limit, carried, judged)
        dup[orphan], repeats[orphan] = True, -1
