"""Where to measure an FRF: frequency lines designed for the subspace identification.

The identification places each line ``w`` on the unit circle at the angle
``wd = 2 arctan(w T / 2)`` (:mod:`automodal.core.bilinear`). Equidistant lines in ``w``
bunch up at small angles and thin out towards the band's top; lines equidistant in ``wd``
undo that but, for a fixed number of lines, take lines away from the resonances, where the
modal parameters are decided (``docs/design.md``). The rule here keeps both:

* a **background** of lines uniform in the mapped angle ``wd`` (so the whole band is seen
  evenly by the polynomial rows of the subspace method), and
* per expected mode, lines uniform in the **phase angle of its resonance**,
  ``theta = arctan((w - w_r) / (zeta_r w_r))``: their density is a Lorentzian (Cauchy)
  bump of half-width ``zeta_r w_r``, half of it inside the mode's half-power band
  ``w_r (1 +- zeta_r)``. Equal steps of the phase angle are equal steps along the mode's
  circle in the Nyquist plane, where a single-mode FRF's information on its pole lies.

The lines are the quantiles of the mixture density at ``k / (N - 1)``, so the band's edges
are lines (the identification's bilinear scale, taken from the first and last line, is the
same as for equidistant lines over the band) and the lines are sorted and distinct. Other
rules (equidistant, uniform in ``wd``, greedy D-optimal) are kept for comparison;
``benchmarks/bench_design.py`` measures them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from automodal.core.bilinear import default_scale

__all__ = [
    "MODAL_SHARE",
    "RULES",
    "LineDesign",
    "design_lines",
    "half_power_counts",
    "mapped_angle",
]

RULES = ("modal", "dt-uniform", "equidistant", "d-optimal")
"""The rules :func:`design_lines` knows; ``"modal"`` is the default (see the module)."""

MODAL_SHARE = 0.75
"""Fraction of the lines given to the expected modes (the rest is the background uniform in
the mapped angle). Chosen among 0.25, 0.5, 0.75 and 0.9 on seeds 1-10 of
``benchmarks/bench_design.py`` (the pipeline's damping error, median plus 90th percentile,
over three systems: 0.87, 0.79, 0.70, 0.75; equidistant lines 0.88), judged on seeds 101-120
(``benchmarks/results_design.md``)."""

MAX_LINES = 200_000
"""Most lines a design may ask for (the pipeline decimates larger files to this many)."""

D_OPTIMAL_MAX_LINES = 2000
"""Most lines the greedy D-optimal rule (for comparison only) designs: its cost grows like
``N^2`` times the number of modes squared (6 s for 400 lines and 10 modes)."""

_BISECTION_STEPS = 200


@dataclass(frozen=True)
class LineDesign:
    """Designed frequency lines and what each expected mode gets.

    Attributes
    ----------
    frequency_hz : ndarray, shape (N,)
        The lines (Hz), sorted, distinct, the band's edges included.
    rule : str
        The rule that made them (:data:`RULES`).
    mode_frequency_hz, mode_damping_ratio : ndarray, shape (m,)
        The expected modes the design used (those in the band).
    half_power_lines : ndarray of int, shape (m,)
        Lines inside each mode's half-power band ``f_r (1 +- zeta_r)``.
    guaranteed_lines : ndarray of int, shape (m,)
        What the rule promises inside each half-power band (0 for rules that promise
        nothing); ``half_power_lines >= guaranteed_lines`` always holds.
    bilinear_scale : float
        The scale ``T`` (s) of the identification for this band.
    """

    frequency_hz: np.ndarray
    rule: str
    mode_frequency_hz: np.ndarray
    mode_damping_ratio: np.ndarray
    half_power_lines: np.ndarray
    guaranteed_lines: np.ndarray
    bilinear_scale: float


def mapped_angle(frequency_hz: np.ndarray, T: float) -> np.ndarray:
    """The angle ``wd = 2 arctan(w T / 2)`` (rad) of lines on the unit circle."""
    return 2.0 * np.arctan(np.pi * T * np.asarray(frequency_hz, dtype=float))


def half_power_counts(
    lines_hz: np.ndarray, frequency_hz: np.ndarray, damping_ratio: np.ndarray
) -> np.ndarray:
    """Lines inside each mode's half-power band ``f_r (1 - zeta_r) .. f_r (1 + zeta_r)``."""
    lines = np.sort(np.asarray(lines_hz, dtype=float))
    f = np.asarray(frequency_hz, dtype=float)
    z = np.asarray(damping_ratio, dtype=float)
    lo = np.searchsorted(lines, f * (1.0 - z), side="left")
    hi = np.searchsorted(lines, f * (1.0 + z), side="right")
    return (hi - lo).astype(int)


def _check(band_hz: tuple[float, float], n_lines: int, f: np.ndarray, z: np.ndarray) -> None:
    lo, hi = band_hz
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 <= lo < hi):
        raise ValueError(f"the band must satisfy 0 <= low < high, got [{lo:g}, {hi:g}] Hz")
    if isinstance(n_lines, bool) or int(n_lines) != n_lines or not 3 <= n_lines <= MAX_LINES:
        raise ValueError(f"the number of lines must be an integer from 3 to {MAX_LINES},"
                         f" got {n_lines}")
    if f.shape != z.shape or f.ndim != 1:
        raise ValueError("give one damping ratio per expected frequency")
    if not np.all(np.isfinite(f) & (f > 0)):
        raise ValueError("every expected frequency must be a positive finite number")
    if not np.all(np.isfinite(z) & (z > 0) & (z < 1)):
        raise ValueError("every expected damping ratio must lie strictly between 0 and 1")


def _cdf(x: np.ndarray, T: float, lo: float, hi: float, f: np.ndarray, width: np.ndarray,
         share: float) -> np.ndarray:
    """The mixture's distribution function at ``x`` (Hz), 0 at ``lo`` and 1 at ``hi``; the
    modes' bumps have half-widths ``width`` (Hz)."""
    a_lo, a_hi = mapped_angle(lo, T), mapped_angle(hi, T)
    out = (1.0 - share) * (mapped_angle(x, T) - a_lo) / (a_hi - a_lo)
    if f.size and share > 0:
        t = np.arctan((x[:, None] - f[None, :]) / width[None, :])
        t_lo = np.arctan((lo - f) / width)
        t_hi = np.arctan((hi - f) / width)
        out = out + (share / f.size) * np.sum((t - t_lo) / (t_hi - t_lo), axis=1)
    return out


def _quantiles(u: np.ndarray, T: float, lo: float, hi: float, f: np.ndarray,
               width: np.ndarray, share: float) -> np.ndarray:
    """Invert :func:`_cdf` by bisection (it is continuous and strictly increasing)."""
    a = np.full(u.shape, lo)
    b = np.full(u.shape, hi)
    for _ in range(_BISECTION_STEPS):
        mid = 0.5 * (a + b)
        below = _cdf(mid, T, lo, hi, f, width, share) < u
        a = np.where(below, mid, a)
        b = np.where(below, b, mid)
        if np.all(b - a <= 4 * np.spacing(b)):
            break
    x = 0.5 * (a + b)
    x[0], x[-1] = lo, hi
    return x


def _guaranteed(n: int, lo: float, hi: float, f: np.ndarray, z: np.ndarray, width: np.ndarray,
                share: float) -> np.ndarray:
    """Lines the modal rule puts in each half-power band: the mode's own probability mass
    there times ``N - 1``, less one for the rounding of quantiles at either end."""
    t_lo = np.arctan((lo - f) / width)
    t_hi = np.arctan((hi - f) / width)
    a = np.arctan((np.clip(f * (1 - z), lo, hi) - f) / width)
    b = np.arctan((np.clip(f * (1 + z), lo, hi) - f) / width)
    mass = (share / f.size) * (b - a) / (t_hi - t_lo)
    return np.maximum(np.floor(mass * (n - 1)).astype(int) - 1, 0)


def _d_optimal(n: int, lo: float, hi: float, f: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Greedy D-optimal lines from a fine grid for the modal parameters.

    Model: ``H(w) = sum_r R_r / (j w - l_r) + conj`` with residues scaled so every mode's peak
    is one (well-separated modes make ``log det`` of the information matrix nearly blind to
    that scale); parameters ``Re l_r, Im l_r, Re R_r, Im R_r``; white noise of one level.
    Lines are added one at a time where they raise ``log det`` most, from a grid of
    ``10 N`` candidates uniform in frequency plus ``20`` per half-power bandwidth, the band
    edges first.
    """
    lam = -z * 2 * np.pi * f + 2j * np.pi * f * np.sqrt(1 - z**2)
    R = -1j * (z * 2 * np.pi * f)  # peak |R / (j w - l)| = 1 at resonance
    cand = [np.linspace(lo, hi, 10 * n)]
    for fr, zr in zip(f, z, strict=True):
        cand.append(np.linspace(fr * (1 - 5 * zr), fr * (1 + 5 * zr), 200))
    grid = np.unique(np.clip(np.concatenate(cand), lo, hi))
    s = 2j * np.pi * grid[:, None]
    d1 = 1.0 / (s - lam[None, :])
    d2 = 1.0 / (s - lam.conj()[None, :])
    # derivatives of H w.r.t. (Re l, Im l, Re R, Im R) per mode
    g_re_l = R * d1**2 + R.conj() * d2**2
    g_im_l = 1j * (R * d1**2 - R.conj() * d2**2)
    g_re_r = d1 + d2
    g_im_r = 1j * (d1 - d2)
    G = np.concatenate([g_re_l, g_im_l, g_re_r, g_im_r], axis=1)  # (M, 4m) complex
    Gr = np.stack([G.real, G.imag], axis=1)  # (M, 2, p)
    p = G.shape[1]
    chosen = np.zeros(grid.size, bool)
    chosen[[0, -1]] = True
    info = np.einsum("kip,kiq->pq", Gr[chosen], Gr[chosen]) + 1e-9 * np.eye(p)
    for _ in range(n - 2):
        inv = np.linalg.inv(info)
        # det(I_2 + G_k inv G_k^T) for every candidate
        S = np.einsum("kiq,kjq->kij", (Gr.reshape(-1, p) @ inv).reshape(Gr.shape), Gr)
        gain = (1 + S[:, 0, 0]) * (1 + S[:, 1, 1]) - S[:, 0, 1] * S[:, 1, 0]
        gain[chosen] = -np.inf
        k = int(np.argmax(gain))
        chosen[k] = True
        info += Gr[k].T @ Gr[k]
    return grid[chosen]


def design_lines(
    band_hz: tuple[float, float],
    n_lines: int,
    frequency_hz: np.ndarray,
    damping_ratio: np.ndarray,
    rule: str = "modal",
    modal_share: float = MODAL_SHARE,
    frequency_uncertainty: float = 0.0,
) -> LineDesign:
    """The ``n_lines`` frequency lines to measure over ``band_hz`` for the expected modes.

    Parameters
    ----------
    band_hz : (float, float)
        The band ``(low, high)`` in Hz, ``0 <= low < high``; both edges are lines.
    n_lines : int
        Number of lines, 3 to :data:`MAX_LINES`.
    frequency_hz, damping_ratio : array_like, shape (m,)
        The expected modes (natural frequency in Hz, damping ratio in ``(0, 1)``). Modes whose
        half-power band lies wholly outside ``band_hz`` are left out; at least one must stay.
    rule : str
        ``"modal"`` (the module's rule), ``"dt-uniform"`` (uniform in the mapped angle),
        ``"equidistant"`` or ``"d-optimal"`` (greedy, for comparison).
    modal_share : float
        ``"modal"`` only: the fraction of lines on the modes, in ``[0, 1)``.
    frequency_uncertainty : float
        ``"modal"`` only: how far off (relative, ``>= 0``) the expected frequencies may be. A
        mode's bump gets the half-width ``f_r max(zeta_r, frequency_uncertainty)``, so that
        its lines still cover the resonance where it really is.

    Returns
    -------
    LineDesign

    Raises
    ------
    ValueError
        On a bad band, count, mode, rule or share, no expected mode in the band, or a design
        whose lines would not be distinct in floating point (modes too narrow for ``N``).
    """
    f = np.atleast_1d(np.asarray(frequency_hz, dtype=float))
    z = np.atleast_1d(np.asarray(damping_ratio, dtype=float))
    lo, hi = float(band_hz[0]), float(band_hz[1])
    _check((lo, hi), n_lines, f, z)
    if rule not in RULES:
        raise ValueError(f"unknown rule {rule!r}: one of {', '.join(RULES)}")
    if not (math.isfinite(modal_share) and 0 <= modal_share < 1):
        raise ValueError(f"the modal share must lie in [0, 1), got {modal_share}")
    if not (math.isfinite(frequency_uncertainty) and 0 <= frequency_uncertainty < 1):
        raise ValueError("the frequency uncertainty must lie in [0, 1), got"
                         f" {frequency_uncertainty}")
    n = int(n_lines)
    if rule == "d-optimal" and n > D_OPTIMAL_MAX_LINES:
        raise ValueError(f"the d-optimal rule designs at most {D_OPTIMAL_MAX_LINES} lines,"
                         f" not {n}; use the modal rule")
    inside = (f * (1 + z) >= lo) & (f * (1 - z) <= hi)
    if not np.any(inside):
        raise ValueError(f"no expected mode lies in the band [{lo:g}, {hi:g}] Hz")
    f, z = f[inside], z[inside]
    order = np.argsort(f, kind="stable")
    f, z = f[order], z[order]
    T = default_scale(2 * np.pi * lo, 2 * np.pi * hi)
    u = np.linspace(0.0, 1.0, n)
    guaranteed = np.zeros(f.size, int)
    if rule == "equidistant":
        lines = np.linspace(lo, hi, n)
    elif rule == "dt-uniform":
        lines = _quantiles(u, T, lo, hi, f, z * f, 0.0)
    elif rule == "modal":
        width = f * np.maximum(z, frequency_uncertainty)
        lines = _quantiles(u, T, lo, hi, f, width, modal_share)
        guaranteed = _guaranteed(n, lo, hi, f, z, width, modal_share)
    else:
        lines = _d_optimal(n, lo, hi, f, z)
    if not (lines.size == n and np.all(np.diff(lines) > 0)):
        raise ValueError(f"{n} distinct lines cannot be placed: the expected modes are too"
                         " narrow for the floating-point resolution of the band; give fewer"
                         " lines or a narrower band")
    counts = half_power_counts(lines, f, z)
    return LineDesign(frequency_hz=lines, rule=rule, mode_frequency_hz=f,
                      mode_damping_ratio=z, half_power_lines=counts,
                      guaranteed_lines=guaranteed, bilinear_scale=T)
