"""Empirical-Bayes shrinkage of estimates whose errors differ from entry to entry.

A mode's residue is estimated entry by entry, each with its own error variance. Where one
output's noise at the mode's lines is far larger than the mode's response in the other
outputs (noise proportional to ``|H|`` on a channel that another mode dominates there),
that entry's estimate is mostly error, yet as large as the true entries: the least-squares
shape then points at the noisy channel, however well the others are known.

Under a prior of independent entries of mean zero and a common variance ``tau^2``, with
``r_e = x_e + error_e`` and ``error_e ~ CN(0, s_e)``, the posterior mean of ``x_e`` is
``r_e tau^2 / (tau^2 + s_e)``. ``tau^2`` is taken from the data themselves, as the maximum of
the marginal likelihood ``r_e ~ CN(0, tau^2 + s_e)`` (Efron and Morris 1973, 1975: the
James-Stein estimator for unequal variances). An entry known far better than the entries'
size keeps its value to ``s_e / tau^2``; an entry whose error exceeds it goes to about
zero. Error-free estimates (all ``s_e = 0``) are returned as they are.
"""

from __future__ import annotations

import numpy as np

PRIOR_RANGE = 1e-30
"""The prior variance is searched between this share of the largest ``|r_e|^2`` and that
largest value (beyond it the likelihood only falls)."""

PRIOR_TOLERANCE = 1e-9
"""Relative width at which the bisection for the prior variance stops. A bisection on the
logarithm, not ``scipy.optimize.brentq``: importing ``scipy.optimize`` costs 0.3-0.4 s, a
fifth of a typical run, for a root the bisection finds in about 40 halvings."""


def prior_variance(r: np.ndarray, s: np.ndarray) -> float:
    """The maximum-likelihood common prior variance ``tau^2`` of entries ``r`` (complex)
    with error variances ``s`` (``E |error|^2``, non-negative, as ``r``).

    Returns 0 when the entries are as small as their errors (no prior variance above
    ``PRIOR_RANGE`` times the largest ``|r|^2`` raises the likelihood), ``inf`` when every
    ``s`` is zero.
    """
    p = np.abs(np.asarray(r, dtype=complex)).ravel() ** 2
    s = np.asarray(s, dtype=float).ravel()
    if not np.any(s > 0):
        return np.inf
    top = float(np.max(p))
    if top <= 0.0:
        return 0.0

    def slope(log_t: float) -> float:  # the sign of d log L / d tau^2 at tau^2 = e^log_t
        v = np.exp(log_t) + s
        return float(np.sum((p - v) / v**2))

    lo, hi = np.log(top * PRIOR_RANGE), np.log(top)
    if slope(lo) <= 0.0:
        return 0.0
    if slope(hi) >= 0.0:
        return top
    while hi - lo > PRIOR_TOLERANCE:
        mid = 0.5 * (lo + hi)
        if slope(mid) > 0.0:
            lo = mid
        else:
            hi = mid
    return float(np.exp(0.5 * (lo + hi)))


def shrunk(r: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Posterior means ``r tau^2 / (tau^2 + s)`` of the entries ``r`` with error variances
    ``s`` (see the module's notes), ``tau^2`` from :func:`prior_variance`.

    Parameters
    ----------
    r : ndarray, complex
        Estimates.
    s : ndarray
        Their error variances (``E |error|^2``), the shape of ``r``; NaN anywhere leaves
        ``r`` as it is.

    Returns
    -------
    ndarray
        The shrunk estimates, the shape of ``r``; zeros when no entry stands out of its
        error.
    """
    r = np.asarray(r, dtype=complex)
    s = np.asarray(s, dtype=float)
    if not np.all(np.isfinite(s)):
        return r
    t = prior_variance(r, s)
    if np.isinf(t):
        return r
    if t == 0.0:
        return np.zeros_like(r)
    return r * (t / (t + s))
