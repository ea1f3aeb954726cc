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
correction.

The weighting is separable: the noise variance of line ``k`` and entry ``e`` is fitted as
``v_k c_e`` (a two-way model of its logarithm), so every entry shares one basis; the
sandwich accounts for what that model misses.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

MAX_ITERATIONS = 30
"""Gauss-Newton (Levenberg-Marquardt) iterations at most; from the subspace estimate the
fit converges in a few."""

RELATIVE_TOLERANCE = 1e-12
"""Stop when an accepted step lowers the cost by less than this share of it."""

STEP_TOLERANCE = 1e-3
"""Or when an accepted step moves every pole parameter by less than this share of its
standard deviation (from the Gauss-Newton matrix): further steps change nothing a report
shows, and on a 23 x 3 dense grid of 3000 lines they took most of 64 iterations."""

MAX_MOVE = 3.0
"""A refined pole may move at most this many of its half-power half-bandwidths
(``|Re lambda|``) from the subspace estimate; one that moves further (a fit that drifted
to a neighbour or into noise) is not refined, and keeps its bootstrap statistics."""

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
        noise model's inverse Fisher information, else the latter; NaN where ``refined``
        is False.
    dispersion : ndarray, shape (m,)
        Trace of the robust (line-clustered sandwich) covariance over that of the noise
        model's inverse Fisher information (about 1 when the model and the noise model
        agree; more when the residual exceeds the noise or is correlated across entries).
    refined : ndarray of bool, shape (m,)
        Whether each pole was refined.
    iterations : int
        Gauss-Newton iterations of the last fit.
    """

    poles: np.ndarray
    covariance: np.ndarray
    dispersion: np.ndarray
    refined: np.ndarray
    iterations: int

    def frequency_damping(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Natural frequency (Hz) and damping ratio of each pole with their standard
        deviations (delta method: ``f = |lambda| / 2 pi``, ``zeta = -Re lambda / |lambda|``).

        Returns
        -------
        f, f_std, zeta, zeta_std : ndarray, shape (m,)
        """
        lam = self.poles
        a = np.abs(lam)
        s, w = lam.real, lam.imag
        grad_f = np.stack([s, w], axis=-1) / (2 * np.pi * a[:, None])
        grad_z = np.stack([-(w**2), s * w], axis=-1) / (a[:, None] ** 3)
        var_f = np.einsum("mi,mij,mj->m", grad_f, self.covariance, grad_f)
        var_z = np.einsum("mi,mij,mj->m", grad_z, self.covariance, grad_z)
        return a / (2 * np.pi), np.sqrt(var_f), -s / a, np.sqrt(var_z)


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
    regression)."""

    s: np.ndarray  # i omega, (N,)
    sw: np.ndarray  # square root of the line weights, (N,)
    Qf: np.ndarray  # orthonormal basis of the weighted fixed columns, (2N, p)
    Yf: np.ndarray  # whitened data, fixed part projected out, (2N, E)

    @classmethod
    def make(cls, s: np.ndarray, sw: np.ndarray, Y: np.ndarray, fixed: np.ndarray) -> _Problem:
        Qf = _orthonormal(_stack(sw[:, None] * _fixed_columns(s, fixed)))
        Ys = _stack(Y)
        return cls(s=s, sw=sw, Qf=Qf, Yf=Ys - Qf @ (Qf.T @ Ys))

    def off_fixed(self, X: np.ndarray) -> np.ndarray:
        """Stacked ``X`` with the fixed columns projected out."""
        return X - self.Qf @ (self.Qf.T @ X)


def _orthonormal(Phi: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the column space of ``Phi`` (columns normalised first; columns
    that add nothing numerically are dropped)."""
    norms = np.linalg.norm(Phi, axis=0)
    U, sv, _ = np.linalg.svd(Phi / np.where(norms > 0, norms, 1.0)[None, :],
                             full_matrices=False)
    return U[:, sv > sv[0] * 1e-10] if sv.size else U


def _fit(
    prob: _Problem, free: np.ndarray
) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    """Residues of the free poles and residual of the linear fit at given free poles.

    Returns ``cost, C, R, Qp``: the squared residual summed, the real coefficients
    ``(2m, E)`` of :func:`_pair_columns` (``Re``, ``Im`` of each residue in turn), the
    stacked residual ``(2N, E)`` and the orthonormal basis of the free columns off the
    fixed ones.
    """
    P = prob.off_fixed(_stack(prob.sw[:, None] * _pair_columns(prob.s, free)))
    norms = np.linalg.norm(P, axis=0)
    norms = np.where(norms > 0, norms, 1.0)
    Qp, Rt = np.linalg.qr(P / norms[None, :])
    QY = Qp.T @ prob.Yf
    R = prob.Yf - Qp @ QY
    try:
        C = np.linalg.solve(Rt, QY) / norms[:, None]
    except np.linalg.LinAlgError:
        C = np.linalg.lstsq(Rt, QY, rcond=None)[0] / norms[:, None]
    return float(np.sum(R * R)), C, R, Qp


def _jacobian_parts(
    prob: _Problem, free: np.ndarray, C: np.ndarray, Qp: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Derivative columns ``D`` (stacked, ``(2N, 4m)``), the same projected off the whole
    basis (``PD``) and the coefficient row that multiplies each (``(4m, E)``): Kaufman's
    Jacobian of parameter ``t`` (``Re lambda_r`` or ``Im lambda_r``) is
    ``-sum PD[:, a] Cx[a]^T`` over its two columns ``a``."""
    D = _stack(prob.sw[:, None] * _pair_derivatives(prob.s, free))
    PD = prob.off_fixed(D)
    PD = PD - Qp @ (Qp.T @ PD)
    Cx = np.repeat(C.reshape(free.size, 2, -1)[:, None], 2, axis=1).reshape(4 * free.size, -1)
    return D, PD, Cx


def _normal_equations(
    prob: _Problem, free: np.ndarray, C: np.ndarray, R: np.ndarray, Qp: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Newton normal matrix ``J^T J`` and gradient ``J^T r`` in the real parameters
    ``(Re lambda_1, Im lambda_1, ...)`` (variable projection with Kaufman's Jacobian)."""
    D, PD, Cx = _jacobian_parts(prob, free, C, Qp)
    W = (PD.T @ PD) * (Cx @ Cx.T)
    u = np.sum(Cx * (D.T @ R), axis=1)  # R is orthogonal to the basis: D^T R = PD^T R
    # parameter t owns columns 2t and 2t + 1 of D
    n = 2 * free.size
    normal = W.reshape(n, 2, n, 2).sum(axis=(1, 3))
    grad = -u.reshape(n, 2).sum(axis=1)
    return normal, grad


def _gauss_newton(
    prob: _Problem, free: np.ndarray, max_iterations: int,
    strayed: Callable[[np.ndarray], np.ndarray] | None = None,
) -> tuple[np.ndarray, int]:
    """Levenberg-Marquardt on the free poles; returns them and the iterations taken.

    ``strayed(poles)`` (a boolean mask) ends the fit as soon as a pole has left what a
    refinement may do: the caller holds it fixed and fits again, so the remaining
    iterations would be wasted."""
    cost, C, R, Qp = _fit(prob, free)
    damping = 1e-3
    it = 0
    for _ in range(max_iterations):
        it += 1
        normal, grad = _normal_equations(prob, free, C, R, Qp)
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
            t_cost, t_C, t_R, t_Q = _fit(prob, trial)
            if np.isfinite(t_cost) and t_cost <= cost:
                gain = cost - t_cost
                free, cost, C, R, Qp = trial, t_cost, t_C, t_R, t_Q
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
    return free, it


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


def refine_poles(
    omega: np.ndarray,
    H: np.ndarray,
    variance: np.ndarray,
    free: np.ndarray,
    fixed: np.ndarray,
    max_iterations: int = MAX_ITERATIONS,
) -> PoleRefinement:
    """Refine the poles ``free`` of a pole-residue model of ``H`` by weighted least squares.

    Parameters
    ----------
    omega : ndarray, shape (N,)
        Lines (rad/s), positive.
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
        Gauss-Newton iterations at most.

    Returns
    -------
    PoleRefinement
        A pole that moved more than :data:`MAX_MOVE` half-bandwidths, turned unstable or
        whose information is singular is not refined (the fit is then repeated with it
        fixed at its start).

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
    m = free0.size
    nan_cov = np.full((m, 2, 2), np.nan)
    if m == 0 or N < 2 * (2 * m + fixed.size + 1):
        return PoleRefinement(free0.copy(), nan_cov, np.full(m, np.nan), np.zeros(m, bool), 0)
    line_var, entry_var = separable_weights(np.asarray(variance, float).reshape(N, -1))
    sw = 1.0 / np.sqrt(line_var)
    entry_std = np.sqrt(entry_var)
    Y = sw[:, None] * H.reshape(N, -1) / entry_std[None, :]
    s = 1j * omega
    ok = np.ones(m, bool)
    poles, it, prob = free0.copy(), 0, None
    for _ in range(3):  # refit with the poles that failed held fixed
        idx = np.flatnonzero(ok)
        prob = _Problem.make(s, sw, Y, np.concatenate([free0[~ok], fixed]))
        start = free0[idx]

        def strayed(got: np.ndarray, start: np.ndarray = start) -> np.ndarray:
            half = np.maximum(np.abs(start.real), 1e-12)
            ratio = np.abs(got.real) / half
            return ((np.abs(got - start) > MAX_MOVE * half) | (got.real >= 0)
                    | (got.imag <= 0) | (ratio > MAX_DAMPING_CHANGE)
                    | (ratio < 1.0 / MAX_DAMPING_CHANGE))

        got, it = _gauss_newton(prob, start, max_iterations, strayed)
        bad = strayed(got)
        ok[idx[bad]] = False
        if not bad.any():
            poles[idx] = got
            break
        if not ok.any():
            break
    else:  # still failing after the last refit: nothing is refined
        ok[:] = False
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return PoleRefinement(free0.copy(), nan_cov, np.full(m, np.nan), ok, it)
    cost, C, R, Qp = _fit(prob, poles[idx])
    normal, _ = _normal_equations(prob, poles[idx], C, R, Qp)
    try:
        info_inv = np.linalg.inv(normal)
    except np.linalg.LinAlgError:
        info_inv = np.full_like(normal, np.nan)
    # each complex whitened residual has E|e|^2 = 1: real and imaginary parts 1/2 each
    cov_free = 0.5 * np.stack([info_inv[2 * i: 2 * i + 2, 2 * i: 2 * i + 2]
                               for i in range(idx.size)])
    # leverage of the linear part per stacked row; residuals corrected for it
    leverage = np.clip(np.sum(prob.Qf**2, axis=1) + np.sum(Qp**2, axis=1), 0.0, 1.0 - 1e-9)
    Rc = R / np.sqrt(1.0 - leverage)[:, None]
    _, PD, Cx = _jacobian_parts(prob, poles[idx], C, Qp)
    # clustered sandwich: the scores of each block of CLUSTER_LINES lines over all their
    # entries (real and imaginary rows together), so errors correlated across the entries
    # of a line (an H1 estimate's shared force noise) or between neighbouring lines (a
    # window's leakage), or not matching the separable model, count as they are
    score = -(PD * (Rc @ Cx.T))  # (2N, 4m): per row, each derivative column's share
    score = _block_sums(score.reshape(score.shape[0], -1, 2).sum(axis=2))  # (blocks, 2m)
    robust = info_inv @ (score.T @ score) @ info_inv
    # where each pole's information lies, per block: its effective number of blocks (Kish)
    # sets a small-sample correction of the sandwich
    info = _block_sums(PD**2 * np.sum(Cx**2, axis=1)[None, :])
    info = info.reshape(info.shape[0], -1, 4).sum(axis=2)  # per pole, (blocks, m)
    disp = np.full(m, np.nan)
    cov = nan_cov.copy()
    for j, i in enumerate(idx):
        block = slice(2 * j, 2 * j + 2)
        model = cov_free[j]
        g = float(np.sum(info[:, j]) ** 2 / max(np.sum(info[:, j] ** 2), 1e-300))
        sand = robust[block, block] * _small_sample(g)
        # the larger of the model's and the data's covariance: the sandwich alone is noisy
        # when a sharp resonance spreads its information over a few lines
        disp[i] = float(np.trace(sand) / np.trace(model)) if np.trace(model) > 0 else np.nan
        cov[i] = sand if np.isfinite(disp[i]) and disp[i] > 1.0 else model
        if not np.all(np.isfinite(cov[i])) or cov[i, 0, 0] < 0 or cov[i, 1, 1] < 0:
            ok[i] = False
            poles[i] = free0[i]
            cov[i] = np.nan
    return PoleRefinement(poles=poles, covariance=cov, dispersion=disp, refined=ok,
                          iterations=it)
