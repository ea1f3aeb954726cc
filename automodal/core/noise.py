"""A model of the noise on FRF data: the variance of every FRF entry at every line.

Three sources, from the best to the weakest (:func:`estimate_noise` takes the best present):

* **records** (:func:`records_variance`): repeated measurements whose mean is the FRF. The
  variance of the mean is the sample variance over records divided by their number. Records
  whose mean is *not* the FRF (force-weighted H1 records: the FRF is
  ``sum |U_r|^2 X_r / sum |U_r|^2``) are heavy tailed ratios; they then give the number of
  averages for the coherence law, or, without coherence, a median-based estimate
  (:func:`ratio_records_variance`).
* **coherence** (:func:`coherence_variance`): the random-error law of the H1 estimate
  (Bendat & Piersol), ``var(H1) = (1 - g^2) / (g^2 n_d) |H|^2`` per entry, with ``n_d`` the
  number of averages, corrected for the degrees of freedom the regression on the inputs uses.
* **data** (:func:`data_variance`): the FRF alone. A local polynomial over neighbouring lines
  removes the smooth FRF; the residual gives a local variance with known degrees of freedom
  (:func:`local_polynomial_variance`, after Pintelon & Schoukens' local polynomial method).
  A smooth model ``var_k = a + b |H_k|^2`` per FRF entry (a sensor floor plus a
  proportional part) is fitted to these local values by a trimmed gamma regression
  (:func:`fit_floor_proportional`), so that resonances, where the polynomial fits the FRF
  badly, do not inflate it.

Conventions: ``frf`` is ``(N, ny, nu)`` complex on equidistant lines; a *variance* is
``E |H_est - H|^2`` (the sum of the variances of the real and the imaginary parts) of one
entry at one line, ``(N, ny, nu)`` float. Every variance returned is finite and at least
:func:`precision_floor`, so ``frf / sqrt(variance)`` is always defined.

References
----------
J. S. Bendat, A. G. Piersol, *Random Data: Analysis and Measurement Procedures*, 4th ed.,
Wiley 2010, section 9.2 (random errors of frequency response estimates).
R. Pintelon, J. Schoukens, *System Identification: A Frequency Domain Approach*, 2nd ed.,
Wiley-IEEE 2012, chapter 7 (the local polynomial method; nonparametric noise models).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.special import gammainc, gammaincinv  # chi-square via the incomplete gamma

__all__ = [
    "AVERAGES_ATTRIBUTES",
    "NoiseEstimate",
    "averages_from_attributes",
    "coherence_variance",
    "data_variance",
    "estimate_noise",
    "fit_floor_proportional",
    "local_polynomial_variance",
    "mean_as_precise",
    "precision_floor",
    "ratio_records_variance",
    "records_are_mean",
    "records_variance",
]

AVERAGES_ATTRIBUTES = (
    "n_averages",
    "averages",
    "number_of_averages",
    "num_averages",
    "n_avg",
    "navg",
)
"""File attributes read as the number of averages of an H1 estimate (the FRF file spec, version
1, names none; ``n_averages`` is the name proposed for it)."""

MAX_AVERAGES = 1e9
"""The most averages an attribute may state: no test averages more (a billion records of a
millisecond each take 12 days); a larger number is a mistake, and 1e200 overflowed the
coherence law's variance (an internal error)."""

FLOOR_EPS = 16.0
"""The precision floor is the variance of an error of ``FLOOR_EPS`` units in the last place of
the entry's RMS magnitude (see :func:`precision_floor`)."""

LOCAL_HALF_WIDTH = 5
"""Half width ``n`` of the local window (``2 n + 1`` lines) of the data-alone estimate."""

LOCAL_DEGREE = 6
"""Degree of the local polynomial of the data-alone estimate."""

TRIM_PROBABILITY = 0.02
"""Upper tail probability of a local variance under the model above which a line is left out of
the fit of the smooth model (resonances the local polynomial does not follow)."""

VARIANCE_ACCURACY = 1.44
"""How far a noise variance estimate is trusted, as a factor either way: a standard deviation
off by 20 %, the accuracy issue 13 asks of every source. A model that leaves the data less
than this factor (and the chance of the residual's own scatter) beyond the noise fits them
to the noise (:func:`automodal.core.refine.pair_verdicts`)."""

AVERAGES_AGREEMENT = VARIANCE_ACCURACY
"""A stated number of averages disagrees with the data when the coherence law's variance with it
and with the averages the data's own scatter implies (:func:`_calibrated_averages`) differ by
more than this factor either way (:data:`VARIANCE_ACCURACY`). On the 39 H1 files of the family
seeds 977-1039 the data's own averages gave the law's scale within 0.92-1.06 of the true one."""

MEAN_TOLERANCE = 0.01
""":func:`records_are_mean`: the FRF is the records' mean when its mean squared distance from it
is below this fraction of the variance of the mean."""


@dataclass(frozen=True)
class NoiseEstimate:
    """The noise variance of every FRF entry at every line, and where it came from.

    Attributes
    ----------
    variance : ndarray, shape (N, ny, nu), float
        ``E |H_est - H|^2`` per line and entry, finite and > 0.
    source : str
        ``"records"``, ``"coherence"`` or ``"data"``.
    level : ndarray, shape (ny, nu)
        Relative noise level of each entry: RMS over lines of the std over RMS of ``|H|``.
    floor : ndarray, shape (ny, nu) or None
        ``a`` of the smooth model ``a + b |H|^2`` (source ``"data"``).
    proportional : ndarray, shape (ny, nu) or None
        ``b`` of that model (source ``"data"``): ``sqrt(b)`` is the proportional noise level.
    n_averages : float or None
        The number of averages used by the coherence law (source ``"coherence"``).
    assumptions : tuple of str
        What was assumed, in words, for a report.
    conflicts : tuple of str
        Where a stated property of the data disagrees with the data, in words, for a
        warning (a file's number of averages against the scatter of its FRF,
        :data:`AVERAGES_AGREEMENT`).
    """

    variance: np.ndarray
    source: str
    level: np.ndarray
    floor: np.ndarray | None = None
    proportional: np.ndarray | None = None
    n_averages: float | None = None
    assumptions: tuple[str, ...] = field(default_factory=tuple)
    conflicts: tuple[str, ...] = field(default_factory=tuple)

    @property
    def std(self) -> np.ndarray:
        """Noise standard deviation per line and entry, ``sqrt(variance)``."""
        return np.sqrt(self.variance)

    @property
    def output_level(self) -> np.ndarray:
        """Relative noise level per output channel (RMS of :attr:`level` over inputs), (ny,)."""
        return np.sqrt(np.mean(self.level**2, axis=1))


# ---------------------------------------------------------------------------------------
# Helpers
# ---------------------------------------------------------------------------------------


def precision_floor(frf: np.ndarray) -> np.ndarray:
    """Smallest variance any estimate returns: rounding noise of the FRF's own precision.

    Model: an entry stored in floating point carries an error of a few units in the last
    place of its magnitude; ``floor = (FLOOR_EPS eps rms_k |H_k|)^2`` per entry, ``eps`` the
    machine precision of ``frf``'s dtype (``complex64``: 1.2e-7, ``complex128``: 2.2e-16).
    An all-zero entry gets the floor of the largest entry (or the smallest positive normal).

    Parameters
    ----------
    frf : ndarray, shape (N, ny, nu), complex

    Returns
    -------
    ndarray, shape (1, ny, nu), float
    """
    H = np.asarray(frf)
    eps = (
        float(np.finfo(H.dtype).eps)
        if np.iscomplexobj(H) or H.dtype.kind == "f"
        else float(np.finfo(float).eps)
    )
    rms = np.sqrt(np.mean(np.abs(H) ** 2, axis=0, keepdims=True))
    top = float(rms.max()) if rms.size else 0.0
    rms = np.where(rms > 0, rms, top)
    out = (FLOOR_EPS * eps * rms) ** 2
    return np.maximum(out, np.finfo(float).tiny)


def _relative_level(frf: np.ndarray, variance: np.ndarray) -> np.ndarray:
    """RMS over lines of the std over RMS over lines of ``|H|``, per entry ``(ny, nu)``."""
    num = np.sqrt(np.mean(variance, axis=0))
    den = np.sqrt(np.mean(np.abs(frf) ** 2, axis=0))
    return num / np.where(den > 0, den, 1.0)


def averages_from_attributes(attributes: Mapping[str, Any]) -> float | None:
    """The number of averages a file's attributes state, if any.

    Looks for the names in :data:`AVERAGES_ATTRIBUTES` (case-insensitive). The FRF file spec
    (version 1) defines no such attribute; this reads the usual spellings.

    Parameters
    ----------
    attributes : mapping
        Free attributes of the file (``FRFData.attributes``).

    Returns
    -------
    float or None
        A value in ``(1, MAX_AVERAGES]``, or ``None`` (a value outside is not read, as a
        non-number is not).
    """
    lower = {str(k).lower(): v for k, v in attributes.items()}
    for name in AVERAGES_ATTRIBUTES:
        if name in lower:
            try:
                value = float(np.asarray(lower[name]).reshape(-1)[0])
            except (TypeError, ValueError, IndexError):
                continue
            if np.isfinite(value) and 1 < value <= MAX_AVERAGES:
                return value
    return None


# ---------------------------------------------------------------------------------------
# Records
# ---------------------------------------------------------------------------------------


def records_are_mean(
    records: np.ndarray, frf: np.ndarray, tolerance: float = MEAN_TOLERANCE
) -> bool:
    """Whether ``frf`` is the plain mean of ``records`` (to within rounding).

    The test: the mean squared distance between ``frf`` and the records' mean is below
    ``tolerance`` times the mean variance of that mean (sample variance / R). An H1 estimate
    from random force weights each record by its force power and fails it by far.

    Parameters
    ----------
    records : ndarray, shape (R, N, ny, nu), complex
    frf : ndarray, shape (N, ny, nu), complex
    tolerance : float

    Returns
    -------
    bool
    """
    X = np.asarray(records)
    R = X.shape[0]
    if R < 2:
        return False
    mean = X.mean(axis=0)
    var_mean = np.sum(np.abs(X - mean) ** 2, axis=0) / ((R - 1) * R)
    dist = np.mean(np.abs(np.asarray(frf) - mean) ** 2)
    return bool(dist <= tolerance * np.mean(var_mean))


RECORD_MEAN_EFFICIENCY = 1.5
""":func:`mean_as_precise`: the records' mean is as precise an estimate as the FRF when its
variance is at most this many times the FRF's noise variance (median over lines and entries).
Equivalent estimators give about 1 (LADISK's five hammer hits, per-hit FRFs against their H1:
1.07); the mean of single-record ratios ``Y_r / U_r`` under random force, whose heavy tails H1
avoids, gives 2.7, 3.4 and 4.2 for 8, 16 and 32 records (family seeds 281 and 283)."""


def mean_as_precise(
    records: np.ndarray, variance: np.ndarray, efficiency: float = RECORD_MEAN_EFFICIENCY
) -> bool:
    """Whether the plain mean of ``records`` estimates the FRF as precisely as the FRF does.

    A bootstrap over records makes each replicate the mean of a resample of them. That
    reproduces the FRF's estimator, and so its error, only when the FRF is (nearly) that
    mean. An H1 estimate from random force is not: it weights each record by its force
    power, while the mean of ratio records follows every line where one record's force
    happened to be small. The test: the median over lines and entries of the variance of
    the records' mean (:func:`records_variance`) over ``variance`` (the FRF's noise
    variance) is at most ``efficiency``.

    Parameters
    ----------
    records : ndarray, shape (R, N, ny, nu), complex, R >= 2
    variance : ndarray, shape (N, ny, nu)
        The FRF's noise variance (:class:`NoiseEstimate`).
    efficiency : float

    Returns
    -------
    bool
    """
    X = np.asarray(records)
    if X.shape[0] < 2:
        return False
    ratio = records_variance(X) / np.asarray(variance, dtype=float)
    return bool(np.median(ratio) <= efficiency)


def records_variance(records: np.ndarray) -> np.ndarray:
    """Variance of the mean of repeated records, per line and entry.

    Model: the records ``X_r = H + E_r`` (``r = 1..R``) have independent errors of equal
    variance at each line and entry; their mean has the variance
    ``s^2 / R``, ``s^2 = sum_r |X_r - mean|^2 / (R - 1)`` the unbiased sample variance
    (``2 (R - 1)`` real degrees of freedom per line and entry). Model-free in the line: no
    smoothness is assumed (Pintelon & Schoukens 2012, section 2.4, sample mean and
    variance of periodic measurements).

    Parameters
    ----------
    records : ndarray, shape (R, N, ny, nu), complex, R >= 2

    Returns
    -------
    ndarray, shape (N, ny, nu), float (not floored)
    """
    X = np.asarray(records)
    R = X.shape[0]
    if R < 2:
        raise ValueError(f"need at least 2 records, got {R}")
    mean = X.mean(axis=0)
    return np.sum(np.abs(X - mean) ** 2, axis=0) / ((R - 1) * R)


def ratio_records_variance(records: np.ndarray, frf: np.ndarray) -> np.ndarray:
    """Variance of an H1 estimate from its per-record single-input ratios, robustly.

    Model: with one input and random force, record ``r`` is ``X_r = Y_r / U_r = H + N_r / U_r``
    and the FRF is ``H1 = sum |U_r|^2 X_r / sum |U_r|^2`` with
    ``var(H1 | U) = s_n^2 / sum |U_r|^2``. With ``N_r`` and ``U_r`` complex Gaussian the ratio
    ``|X_r - H|^2 (P / s_n^2)`` is the ratio of two unit exponentials, whose median is 1
    (its mean is infinite: the sample variance of such records is useless). So
    ``median_r |X_r - H1|^2 = s_n^2 / P`` and, with ``E[1 / sum |U_r|^2] = 1 / (P (R - 1))``,
    ``var(H1) ~= median_r |X_r - H1|^2 / (R - 1)``. This follows the force's power, not its
    realization at each line (the coherence law does: prefer it when coherence is there).

    Parameters
    ----------
    records : ndarray, shape (R, N, ny, nu), complex, R >= 3
    frf : ndarray, shape (N, ny, nu), complex
        The H1 estimate.

    Returns
    -------
    ndarray, shape (N, ny, nu), float (not floored)
    """
    X = np.asarray(records)
    R = X.shape[0]
    if R < 3:
        raise ValueError(f"need at least 3 records, got {R}")
    return np.median(np.abs(X - np.asarray(frf)[None]) ** 2, axis=0) / (R - 1)


# ---------------------------------------------------------------------------------------
# Coherence
# ---------------------------------------------------------------------------------------


def coherence_variance(
    frf: np.ndarray, coherence: np.ndarray, n_averages: float
) -> np.ndarray:
    """Variance of an H1 estimate from its (ordinary or multiple) coherence.

    One input (Bendat & Piersol 2010, eq. 9.73 and its complex form):
    ``var(H1) = (1 - g^2) / (g^2 (n_d - 1)) |H|^2``: ``(1 - g^2) S_yy`` is the output
    power the input does not explain, whose expectation over ``n_d`` averages is
    ``(n_d - 1) / n_d`` times the noise power (one complex degree of freedom is spent on
    ``H``); dividing by ``n_d - 1`` instead of ``n_d`` removes that bias of the sample coherence.

    Several inputs ``nu`` with the multiple coherence ``g_i^2`` of output ``i`` (as the file
    holds it, repeated along inputs). Assumption: the inputs are uncorrelated and of equal
    power ``P``. Then ``(H S_uu H^H)_ii = P sum_j |H_ij|^2`` and
    ``var(H_ij) = s_i^2 [S_uu^-1]_jj / n_d`` becomes
    ``var(H_ij) = (1 - g_i^2) / g_i^2 sum_j |H_ij|^2 (n_d - 1) / (n_d - nu)^2``:
    ``n_d - nu`` degrees of freedom remain after the regression on ``nu`` inputs, and
    ``(n_d - 1) / (n_d - nu)`` is how much the realized inputs' chance correlation inflates
    ``[S_uu^-1]_jj`` over ``1 / S_uu,jj`` on average (complex Wishart: ``E W^-1 = I / (n_d - nu)``
    and ``E 1 / W_jj = 1 / (n_d - 1)``). With ``nu = 1`` both formulas agree.

    Parameters
    ----------
    frf : ndarray, shape (N, ny, nu), complex
        The H1 estimate.
    coherence : ndarray, shape (N, ny, nu), in [0, 1]
        Ordinary coherence (one input) or the multiple coherence of each output.
    n_averages : float
        Number of averages ``n_d > nu``.

    Returns
    -------
    ndarray, shape (N, ny, nu), float (not floored; zero coherence gives a huge variance, not inf)
    """
    H = np.asarray(frf)
    nu = H.shape[2]
    nd = float(n_averages)
    if not nd > nu:
        raise ValueError(
            f"the number of averages ({nd:g}) must exceed the number of inputs ({nu})"
        )
    g2 = np.clip(np.asarray(coherence, dtype=float), 0.0, 1.0)
    tiny = np.finfo(float).eps
    ratio = (1.0 - g2) / np.maximum(g2, tiny)
    power = np.abs(H) ** 2
    if nu > 1:
        power = np.broadcast_to(power.sum(axis=2, keepdims=True), H.shape)
    return ratio * power * (nd - 1.0) / (nd - nu) ** 2


# ---------------------------------------------------------------------------------------
# Data alone
# ---------------------------------------------------------------------------------------


def _residual_basis(width: int, degree: int) -> np.ndarray:
    """Orthonormal basis ``(width, width - degree - 1)`` of what a polynomial cannot fit."""
    r = np.arange(width, dtype=float) - (width - 1) / 2.0
    V = np.vander(r / max(1.0, (width - 1) / 2.0), degree + 1, increasing=True)
    Q, _ = np.linalg.qr(V, mode="complete")
    return Q[:, degree + 1 :]


def local_polynomial_variance(
    frf: np.ndarray, *, half_width: int = LOCAL_HALF_WIDTH, degree: int = LOCAL_DEGREE
) -> tuple[np.ndarray, int, np.ndarray]:
    """Local noise variance at every line from the misfit of a local polynomial.

    Model (the local polynomial method of Pintelon & Schoukens 2012, section 7.2, with the
    FRF as the local function): on the ``W = 2 n + 1`` lines around line ``k``,
    ``H_{k+r} = sum_{p <= P} c_p r^p + E_{k+r}``, the ``E`` independent, circular, of
    variance ``v_k`` constant over the window. The least-squares residual has
    ``W - P - 1`` complex degrees of freedom, so ``v_k = |residual|^2 / (W - P - 1)`` is
    unbiased and ``2 (W - P - 1) v_k / v`` is chi-square with ``2 (W - P - 1)`` degrees of
    freedom (lines near the ends use the first or last whole window). The residual
    projector is the same for every window, so all lines and entries cost one product with a
    fixed ``W x (W - P - 1)`` basis (a set of higher-order difference filters).

    Where the FRF is not a degree-``P`` polynomial over the window (a resonance with few lines
    per half-power bandwidth) the misfit is added to ``v_k``: a bias upwards only.

    Parameters
    ----------
    frf : ndarray, shape (N, ny, nu), complex
    half_width : int
        ``n`` (the window has ``2 n + 1`` lines).
    degree : int
        ``P`` (``P + 1 < 2 n + 1``).

    Returns
    -------
    local : ndarray, shape (N, ny, nu), float
        ``v_k``.
    dof : int
        Complex degrees of freedom ``W - P - 1`` of each ``v_k``.
    leverage : ndarray, shape (W,)
        Weight of each window line in ``E v_k`` when the variance varies over the window:
        ``E v_k = sum_r leverage_r v_{k+r}`` (the diagonal of the residual projector over
        ``W - P - 1``; sums to 1).
    """
    H = np.asarray(frf)
    N = H.shape[0]
    W = 2 * int(half_width) + 1
    dof = W - int(degree) - 1
    if dof < 1:
        raise ValueError(
            f"a window of {W} lines leaves no degree of freedom to a degree-{degree} polynomial"
        )
    if N < W:
        raise ValueError(f"need at least {W} lines, got {N}")
    Q = _residual_basis(W, int(degree))
    windows = np.lib.stride_tricks.sliding_window_view(
        H, W, axis=0
    )  # (N-W+1, ny, nu, W)
    rss = np.sum(np.abs(windows @ Q) ** 2, axis=-1)
    n = int(half_width)
    local = (
        np.concatenate(
            [np.repeat(rss[:1], n, axis=0), rss, np.repeat(rss[-1:], n, axis=0)]
        )
        / dof
    )
    leverage = np.sum(Q**2, axis=1) / dof
    return local, dof, leverage


def _window_average(x: np.ndarray, leverage: np.ndarray) -> np.ndarray:
    """``sum_r leverage_r x_{k+r}`` with the same end handling as the local variance."""
    W = leverage.size
    n = (W - 1) // 2
    windows = np.lib.stride_tricks.sliding_window_view(x, W, axis=0)
    avg = windows @ leverage
    return np.concatenate(
        [np.repeat(avg[:1], n, axis=0), avg, np.repeat(avg[-1:], n, axis=0)]
    )


def _nonneg_weighted_ls(
    x: np.ndarray, y: np.ndarray, w: np.ndarray
) -> tuple[float, float]:
    """Minimize ``sum w (y - a - b x)^2`` over ``a, b >= 0``."""
    sw, sx, sy = w.sum(), (w * x).sum(), (w * y).sum()
    sxx, sxy = (w * x * x).sum(), (w * x * y).sum()
    det = sw * sxx - sx * sx
    if det > 1e-12 * sw * sxx and sw > 0:
        a = (sxx * sy - sx * sxy) / det
        b = (sw * sxy - sx * sy) / det
        if a >= 0 and b >= 0:
            return float(a), float(b)
    cands = []
    if sw > 0:  # b = 0
        a = max(sy / sw, 0.0)
        cands.append((a, 0.0))
    if sxx > 0:  # a = 0
        b = max(sxy / sxx, 0.0)
        cands.append((0.0, b))
    if not cands:
        return 0.0, 0.0
    cost = [float((w * (y - a - b * x) ** 2).sum()) for a, b in cands]
    return cands[int(np.argmin(cost))]


def fit_floor_proportional(
    local: np.ndarray,
    power: np.ndarray,
    dof: int,
    leverage: np.ndarray,
    *,
    trim_probability: float = TRIM_PROBABILITY,
    iterations: int = 30,
) -> tuple[np.ndarray, np.ndarray]:
    """Fit ``var_k = a + b |H_k|^2`` per entry to local variances, robustly.

    Model: ``local_k = (a + b h~_k) X_k`` with ``h~_k`` the window average (by ``leverage``)
    of ``|H|^2`` and ``X_k ~ chi2(nu) / nu``, ``nu = 2 dof``: a gamma regression with
    identity link, solved by iteratively reweighted least squares (weights ``1 / m_k^2``,
    ``a, b >= 0``). Lines with ``local_k > c m_k``, ``c`` the ``1 - trim_probability``
    quantile of ``X``, are left out (resonances the local polynomial does not follow, which
    only ever inflate ``local``); the fit of what is kept is divided by
    ``E[X | X <= c] = F_{nu+2}(c nu) / F_nu(c nu)`` to undo the trimming.

    Parameters
    ----------
    local : ndarray, shape (N, ny, nu)
        Local variances (:func:`local_polynomial_variance`).
    power : ndarray, shape (N, ny, nu)
        ``|H|^2``.
    dof : int
        Complex degrees of freedom of each local variance.
    leverage : ndarray, shape (W,)
        Window weights of the local variance.
    trim_probability : float
        Tail probability of the trimming threshold.
    iterations : int
        Largest number of reweighting steps.

    Returns
    -------
    a, b : ndarray, shape (ny, nu) each, >= 0
    """
    c, shrink = _trim_constants(dof, trim_probability)
    h_avg = _window_average(power, leverage)
    _, ny, nu = local.shape
    A = np.zeros((ny, nu))
    B = np.zeros((ny, nu))
    for i in range(ny):
        for j in range(nu):
            A[i, j], B[i, j] = _fit_one(
                local[:, i, j], h_avg[:, i, j], c, shrink, iterations
            )
    return A, B


def _trim_constants(dof: int, trim_probability: float) -> tuple[float, float]:
    """The trimming threshold ``c`` of ``X ~ chi2(nu) / nu`` (``nu = 2 dof``: its
    ``1 - trim_probability`` quantile) and ``E[X | X <= c] = F_{nu+2}(c nu) / F_nu(c nu)``."""
    nu_real = 2 * int(dof)
    # chi-square quantile and cdfs through the regularised incomplete gamma function
    # (what scipy.stats.chi2 evaluates, without its 0.3 s import on every run)
    c = 2.0 * float(gammaincinv(nu_real / 2.0, 1.0 - trim_probability)) / nu_real
    shrink = float(gammainc(nu_real / 2.0 + 1.0, c * nu_real / 2.0)
                   / gammainc(nu_real / 2.0, c * nu_real / 2.0))
    return c, shrink


def _fit_one(
    v: np.ndarray, h: np.ndarray, c: float, shrink: float, iterations: int
) -> tuple[float, float]:
    """One entry of :func:`fit_floor_proportional`."""
    scale = float(np.median(v))
    if not scale > 0:
        return 0.0, 0.0
    hs = float(np.median(h)) or 1.0
    vv, hh = v / scale, h / hs  # unit scales for conditioning
    a, b = 1.0, 0.0
    keep = np.ones(v.size, bool)
    for _ in range(iterations):
        m = a + b * hh
        m = np.maximum(m, 1e-12 * max(m.max(), 1e-300))
        new_keep = vv <= c * m
        if new_keep.sum() < 3:
            break
        with np.errstate(over="ignore"):  # a line 1e154 times the median: weight 0
            weight = 1.0 / m[new_keep] ** 2
        a1, b1 = _nonneg_weighted_ls(hh[new_keep], vv[new_keep], weight)
        a1, b1 = a1 / shrink, b1 / shrink
        done = (
            np.array_equal(new_keep, keep)
            and abs(a1 - a) <= 1e-6 * (a + 1e-300) + 1e-12
            and abs(b1 - b) <= 1e-6 * (b + 1e-300) + 1e-12
        )
        a, b, keep = a1, b1, new_keep
        if done:
            break
    return a * scale, b * scale / hs


def data_variance(
    frf: np.ndarray, *, half_width: int = LOCAL_HALF_WIDTH, degree: int = LOCAL_DEGREE
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Noise variance from the FRF alone: local polynomial estimates and a smooth model.

    ``var_k = a + b |H_k|^2`` per entry (:func:`fit_floor_proportional` on
    :func:`local_polynomial_variance`): a sensor floor plus a proportional part.

    Parameters
    ----------
    frf : ndarray, shape (N, ny, nu), complex
    half_width, degree : int
        The local window and polynomial.

    Returns
    -------
    variance : ndarray, shape (N, ny, nu), float (not floored)
    a, b : ndarray, shape (ny, nu)
    """
    H = np.asarray(frf)
    local, dof, leverage = local_polynomial_variance(
        H, half_width=half_width, degree=degree
    )
    power = np.abs(H) ** 2
    a, b = fit_floor_proportional(local, power, dof, leverage)
    return a[None] + b[None] * power, a, b


# ---------------------------------------------------------------------------------------
# Entry point
# ---------------------------------------------------------------------------------------


def estimate_noise(
    frf: np.ndarray,
    *,
    coherence: np.ndarray | None = None,
    records: np.ndarray | None = None,
    n_averages: float | None = None,
) -> NoiseEstimate:
    """The noise variance of every FRF entry at every line, from the best source present.

    Order: records whose mean is the FRF (:func:`records_variance`); else coherence
    (:func:`coherence_variance`) with ``n_d`` from ``n_averages``, else the records' count,
    else calibrated on the local polynomial's residuals (:func:`_calibrated_averages`, said in
    ``assumptions``); else H1 ratio records (:func:`ratio_records_variance`, one input);
    else the data alone (:func:`data_variance`). Every variance is floored at
    :func:`precision_floor`.

    Parameters
    ----------
    frf : ndarray, shape (N, ny, nu), complex
    coherence : ndarray, shape (N, ny, nu), optional
    records : ndarray, shape (R, N, ny, nu), optional
    n_averages : float, optional
        Number of averages of an H1 estimate (e.g. :func:`averages_from_attributes`).

    Returns
    -------
    NoiseEstimate
    """
    H = np.asarray(frf)
    if H.ndim != 3:
        raise ValueError(f"frf must be (N, ny, nu), got shape {H.shape}")
    floor = precision_floor(H)
    notes: list[str] = []
    conflicts: list[str] = []
    a = b = None
    nd_used: float | None = None
    rec = None if records is None else np.asarray(records)
    if rec is not None and (rec.ndim != 4 or rec.shape[1:] != H.shape):
        raise ValueError(
            f"records must be (R, {', '.join(map(str, H.shape))}), got shape {rec.shape}"
        )
    if coherence is not None and np.shape(coherence) != H.shape:
        raise ValueError(
            f"coherence must have the shape of frf {H.shape}, got {np.shape(coherence)}"
        )
    if rec is not None and rec.shape[0] >= 2 and records_are_mean(rec, H):
        var = records_variance(rec)
        source = "records"
        notes.append(
            f"variance of the mean of {rec.shape[0]} records (sample variance / R)"
        )
    elif coherence is not None and not _coherence_is_trivial(coherence, rec, H.shape[2]):
        coh = np.asarray(coherence, dtype=float)
        source = "coherence"
        nu = H.shape[2]
        if n_averages is not None:
            nd_used = float(n_averages)
            notes.append(f"H1 law with n_averages = {nd_used:g} as given")
            conflict = _averages_conflict(H, coh, nd_used)
            if conflict:
                conflicts.append(conflict)
        elif rec is not None and rec.shape[0] > nu:
            nd_used = float(rec.shape[0])
            notes.append(
                f"H1 law with n_averages = {nd_used:g}, the number of records (the FRF is not "
                "their mean)"
            )
        else:
            nd_used = _calibrated_averages(H, coh)
            notes.append(
                f"H1 law with n_averages = {nd_used:.3g} calibrated on the data-alone estimate "
                "(neither given nor implied by records)"
            )
        if nu > 1:
            notes.append(
                "several inputs: assumed uncorrelated and of equal power (multiple coherence "
                "per output)"
            )
        var = coherence_variance(H, coh, nd_used)
    elif rec is not None and rec.shape[0] >= 3 and H.shape[2] == 1:
        var = ratio_records_variance(rec, H)
        source = "records"
        notes.append(
            f"the FRF is not the mean of its {rec.shape[0]} records: taken as H1 of "
            "single-input ratio "
            "records under random force (median-based, follows the force power, not its "
            "realization)"
        )
    else:
        var, a, b = data_variance(H)
        source = "data"
        notes.append(
            f"local polynomial (degree {LOCAL_DEGREE}, {2 * LOCAL_HALF_WIDTH + 1} lines) and "
            "a smooth model "
            "a + b|H|^2 per entry (floor plus proportional noise), independent noise on "
            "neighbouring lines"
        )
        if rec is not None:
            notes.append(
                "records ignored (fewer than 3, or several inputs with an FRF that is not "
                "their mean)"
            )
        if coherence is not None:
            notes.append("coherence ignored: an H1 estimate from as many records as inputs"
                         " (one hammer hit) has coherence 1 at every line, whatever the noise")
    var = np.where(np.isfinite(var), var, np.inf)
    var = np.maximum(np.minimum(var, np.finfo(float).max), floor)
    return NoiseEstimate(
        variance=var,
        source=source,
        level=_relative_level(H, var),
        floor=a,
        proportional=b,
        n_averages=nd_used,
        assumptions=tuple(notes),
        conflicts=tuple(conflicts),
    )


def _averages_conflict(frf: np.ndarray, coherence: np.ndarray, stated: float) -> str:
    """What to say when a stated number of averages disagrees with the data
    (:data:`AVERAGES_AGREEMENT`), else an empty string. A wrong one scales every noise
    variance, and with it every SNR and interval: 40 stated for 8 makes it 5.6 times
    too small with one input, 9.8 with three."""
    nu = frf.shape[2]
    if not stated > nu:
        return ""  # the coherence law refuses it with its own message
    implied = _calibrated_averages(frf, coherence)
    ratio = ((stated - 1) / (stated - nu) ** 2) / ((implied - 1) / (implied - nu) ** 2)
    if 1.0 / AVERAGES_AGREEMENT <= ratio <= AVERAGES_AGREEMENT:
        return ""
    return (f"the file's number of averages, {stated:g}, makes the coherence's noise variance"
            f" {max(ratio, 1.0 / ratio):.3g} times {'larger' if ratio > 1 else 'smaller'} than"
            f" the scatter of the FRF between neighbouring lines shows (as {implied:.3g}"
            " averages would): the file's value is used; if it counts overlapping segments,"
            " or not the averages of this H1 estimate, correct or remove the attribute")


def _coherence_is_trivial(coherence: np.ndarray, records: np.ndarray | None, nu: int) -> bool:
    """Whether a coherence says nothing of the noise: H1 from no more records than inputs
    fits every record exactly, so its coherence is 1 at every line (one hammer hit: the
    coherence law then gave a variance at the precision floor, and the SNR of every mode,
    divided by a dispersion of 1e10, fell below that of noise). A coherence at 1 within
    rounding on every line is read the same way."""
    if records is not None and records.shape[0] <= nu:
        return True
    return bool(np.all(np.asarray(coherence, dtype=float) >= 1.0 - 1e-9))


def _calibrated_averages(frf: np.ndarray, coherence: np.ndarray) -> float:
    """``n_d`` that makes the coherence law agree with the local polynomial's residuals.

    The coherence law is ``var_k = c U_k`` with ``U_k`` its ``n_d``-free part and
    ``c = (n_d - 1) / (n_d - nu)^2``. Under it the local variance
    (:func:`local_polynomial_variance`) is ``local_k = c U~_k X_k``, with ``U~_k`` the window
    average of ``U`` (by the leverage) and ``X_k ~ chi2(2 dof) / (2 dof)``; so ``c`` is the
    mean of ``local_k / U~_k``, trimmed and corrected as in :func:`fit_floor_proportional`
    (resonances the polynomial does not follow only inflate ``local``). ``n_d`` solves
    ``(n_d - 1) / (n_d - nu)^2 = c``. Windows that hold a line of coherence 0 (no law) or
    whose law is 0 throughout (coherence 1) are left out.

    Each line's law enters through its window's average, never alone: at lines where the
    realized force is weak in some direction (and in a band of noise alone, where H1
    regresses noise on the force) ``U_k`` is heavy tailed, and a ratio with ``U_k`` in the
    numerator, as an earlier version took against the smooth data-alone model, was
    dominated by those lines: on a pure-noise band of a 35 x 3 H1 file (8 records) it gave
    ``n_d = 21.8`` for 8 and a variance 3.4 times too small; this gives 9.4, as on the
    file's whole band (8.4).
    """
    nu = frf.shape[2]
    # the law at n_d = nu + 1, where (n_d - 1) / (n_d - nu)^2 = nu, divided by nu
    unit = coherence_variance(frf, coherence, nu + 1.0) / nu
    local, dof, leverage = local_polynomial_variance(frf)
    # a line of coherence 0 has no law (its U is |H|^2 / eps): every window holding one
    # is left out, or its huge U would send that window's ratios to 0 and the trimmed
    # mean after them (a coherence of 0 on one line in 40: n_d = 1.8e18)
    lawless = (np.asarray(coherence, dtype=float) <= np.finfo(float).eps) | ~np.isfinite(unit)
    spoilt = _window_average(lawless.astype(float), leverage) > 0
    average = _window_average(np.where(lawless, 0.0, unit), leverage)
    usable = ~spoilt & (average > 0)
    ratio = local[usable] / average[usable]
    c = _trimmed_scale(ratio[np.isfinite(ratio)], dof)
    if not c > 0:
        return float(nu + 1)
    q = 1.0 / c  # = (n_d - nu)^2 / (n_d - 1)
    # (n_d - nu)^2 = q (n_d - 1): n_d^2 - (2 nu + q) n_d + nu^2 + q = 0, the larger root
    p = 2 * nu + q
    disc = max(p * p - 4 * (nu * nu + q), 0.0)
    return float(max((p + np.sqrt(disc)) / 2.0, nu + 1.0))


def _trimmed_scale(
    ratio: np.ndarray, dof: int, trim_probability: float = TRIM_PROBABILITY,
    iterations: int = 30,
) -> float:
    """``c`` of ``ratio_k = c X_k``, ``X_k ~ chi2(2 dof) / (2 dof)``: the mean of the
    ratios at most the ``1 - trim_probability`` quantile of ``c X``, divided by
    ``E[X | X <= quantile]`` (the trimming of :func:`fit_floor_proportional`), iterated
    from the median; 0 when there is no ratio or at least half of them are 0 (data the
    polynomial fits exactly: the law's scale is then not seen)."""
    if ratio.size == 0:
        return 0.0
    cut, shrink = _trim_constants(dof, trim_probability)
    c = float(np.median(ratio))
    for _ in range(iterations):
        if not c > 0:
            return 0.0
        kept = ratio[ratio <= cut * c]
        new = float(np.mean(kept)) / shrink if kept.size else 0.0
        if abs(new - c) <= 1e-9 * c:
            return new
        c = new
    return c
