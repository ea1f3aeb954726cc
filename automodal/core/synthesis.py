"""FRF synthesis from fixed poles: residues and residual terms by linear least squares.

With the poles ``lambda_r`` of the physical modes fixed, every FRF entry is modelled as

``H(w) = (jw)^p [ sum_r ( R_r / (jw - lambda_r) + S_r / (jw - conj lambda_r) ) + U + L / (jw)^2 ]``

with ``p`` = 0, 1, 2 for receptance, mobility, accelerance (the modes are those of a
displacement model; the factor turns them into the measured quantity). ``U`` is the upper
residual (modes above the band: a constant receptance, a stiffness line) and ``L`` the lower
residual (modes below it, rigid-body motion: a mass line). The model is linear in the
residues and the residuals, so for fixed poles they are the least-squares solution of one
system shared by all channels: the classical least-squares frequency-domain step (LSFD).
The residues are left complex and free, so the fit also absorbs a little non-proportional
damping and noise; the poles, which the identification determined, do not move.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class FixedPoleFit:
    """The least-squares synthesis of :func:`fit_fixed_poles`.

    Attributes
    ----------
    synthesized : ndarray, shape (N, ny, nu)
        The synthesized FRF (modes and residual terms).
    upper, lower : ndarray, shape (ny, nu)
        The residuals ``U`` and ``L`` (receptance units times those of the data).
    normalised_error : ndarray, shape (ny, nu)
        ``sum |H - S|^2 / sum |H|^2`` per channel, over the lines (0: a perfect fit; 1: no
        better than zero; NaN for an all-zero channel).
    poles : ndarray, shape (m,)
        The distinct poles used, in the order of the coefficients.
    coefficients : ndarray, shape (2 m [+ 2], ny * nu)
        The fitted coefficients: the residues ``R_r`` of ``poles``, then those ``S_r`` of
        their conjugates, then (with residuals) ``U`` and ``L``; :func:`synthesize`
        evaluates them at any lines.
    """

    synthesized: np.ndarray
    upper: np.ndarray
    lower: np.ndarray
    normalised_error: np.ndarray
    poles: np.ndarray | None = None
    coefficients: np.ndarray | None = None


def fit_fixed_poles(
    omega: np.ndarray,
    H: np.ndarray,
    poles: np.ndarray,
    power: int = 0,
    residuals: bool = True,
    max_lines: int = 20000,
) -> FixedPoleFit:
    """Residues and residuals of every channel for fixed poles (see the module text).

    Parameters
    ----------
    omega : ndarray, shape (N,)
        Angular frequencies (rad/s), all positive.
    H : ndarray, shape (N, ny, nu)
        The measured FRF.
    poles : ndarray, shape (m,)
        Continuous-time poles (rad/s), one per mode (``Im > 0``); each adds itself and its
        conjugate to the basis. Duplicates are used once.
    power : int
        ``p``: 0 receptance (and output-only half spectra), 1 mobility, 2 accelerance.
    residuals : bool
        Whether the upper and lower residuals are in the model.
    max_lines : int
        The coefficients are fitted on at most this many evenly spread lines (and the
        synthesis evaluated in blocks of as many), which bounds the memory.

    Returns
    -------
    FixedPoleFit
    """
    omega = np.asarray(omega, dtype=float)
    H = np.asarray(H, dtype=complex)
    N, ny, nu = H.shape
    lam = np.unique(np.asarray(poles, dtype=complex).ravel())
    fit = np.unique(np.linspace(0, N - 1, min(N, max_lines)).round().astype(int))
    basis = pole_basis(omega[fit], lam, power, residuals)
    norms = np.linalg.norm(basis, axis=0)
    norms[norms == 0] = 1.0
    if basis.shape[1] == 0:
        coef = np.zeros((0, ny * nu), dtype=complex)
    else:
        rhs = H[fit].reshape(fit.size, ny * nu)
        coef = np.linalg.lstsq(basis / norms, rhs, rcond=None)[0] / norms[:, None]
    S = synthesize(omega, lam, coef, power, residuals, max_lines).reshape(N, ny, nu)
    zero = np.zeros((ny, nu), dtype=complex)
    upper = coef[-2].reshape(ny, nu) if residuals else zero
    lower = coef[-1].reshape(ny, nu) if residuals else zero
    return FixedPoleFit(synthesized=S, upper=upper, lower=lower,
                        normalised_error=normalised_error(H, S), poles=lam, coefficients=coef)


def conjugate_residual_ratio(
    omega: np.ndarray,
    H: np.ndarray,
    poles: np.ndarray,
    power: int = 0,
    max_lines: int = 20000,
) -> tuple[float, int]:
    """How much better the complex conjugate of ``H`` fits decaying poles than ``H`` does.

    The poles are made decaying (``Re lambda = -|Re lambda|``), and both ``H`` and
    ``conj(H)`` are fitted with them as in :func:`fit_fixed_poles` (one least-squares
    projection). An FRF in automodal's sign convention fits well and its conjugate badly;
    one in the other convention the other way round; noise, whose distribution conjugation
    does not change, about equally.

    Parameters
    ----------
    omega : ndarray, shape (N,)
        Angular frequencies (rad/s), all positive.
    H : ndarray, shape (N, ny, nu)
    poles : ndarray, shape (m,)
        Poles (``Im > 0``) of a model of ``H``, of either sign of real part.
    power : int
        As for :func:`fit_fixed_poles`.
    max_lines : int
        As for :func:`fit_fixed_poles`.

    Returns
    -------
    ratio : float
        Residual sum of squares of ``conj(H)`` over that of ``H`` (``inf`` when ``H`` fits
        exactly and its conjugate does not, ``1`` when both do).
    dof : int
        Real degrees of freedom of each residual (``2 (lines - columns) ny nu``).
    """
    H = np.asarray(H, dtype=complex)
    N, ny, nu = H.shape
    lam = np.asarray(poles, dtype=complex).ravel()
    lam = -np.abs(lam.real) + 1j * lam.imag
    residual = []
    for Y in (H, H.conj()):
        fit = fit_fixed_poles(omega, Y, lam, power, max_lines=max_lines)
        residual.append(float(np.sum(np.abs(Y - fit.synthesized) ** 2)))
    k = min(2 * fit.poles.size + 2, N)  # each pole and its conjugate, U and L
    dof = 2 * (N - k) * ny * nu
    if residual[0] == 0:
        return (1.0 if residual[1] == 0 else float("inf")), dof
    return residual[1] / residual[0], dof


def synthesize(
    omega: np.ndarray,
    poles: np.ndarray,
    coefficients: np.ndarray,
    power: int = 0,
    residuals: bool = True,
    max_lines: int = 20000,
) -> np.ndarray:
    """The pole-residue model of the module text at ``omega``: ``(N, n_entries)``.

    Parameters
    ----------
    omega : ndarray, shape (N,)
        Angular frequencies (rad/s), positive.
    poles : ndarray, shape (m,)
        Distinct poles (``Im > 0``), in the order of ``coefficients``.
    coefficients : ndarray, shape (2 m [+ 2], n_entries)
        As :attr:`FixedPoleFit.coefficients`.
    power, residuals, max_lines
        As for :func:`fit_fixed_poles` (``residuals`` must be as the coefficients were fitted).
    """
    omega = np.asarray(omega, dtype=float)
    lam = np.asarray(poles, dtype=complex).ravel()
    coef = np.asarray(coefficients, dtype=complex)
    S = np.empty((omega.size, coef.shape[1]), dtype=complex)
    for start in range(0, omega.size, max_lines):
        rows = slice(start, min(omega.size, start + max_lines))
        S[rows] = pole_basis(omega[rows], lam, power, residuals) @ coef
    return S


def pole_basis(omega: np.ndarray, lam: np.ndarray, power: int, residuals: bool) -> np.ndarray:
    """Columns of the model at ``omega`` (``(N, 2 m [+ 2])``): each pole, its conjugate,
    then ``U`` and ``L``."""
    jw = 1j * omega[:, None]
    columns = [1.0 / (jw - lam[None, :]), 1.0 / (jw - lam.conj()[None, :])]
    if residuals:
        columns += [np.ones((omega.size, 1)), 1.0 / jw**2]
    return np.hstack(columns) * jw**power


def quantity_factor(omega: np.ndarray, power: int, shift: float = 0.0) -> np.ndarray:
    """``(j w + shift)^p``: what a receptance is multiplied by to be the measured quantity.

    Dividing an FRF by it gives its receptance form, and its noise variance is divided by
    ``|(j w + shift)^p|^2``, so the whitened data (FRF over noise standard deviation) are
    the same up to a constant phase. The poles and the mode shapes are unchanged; the
    residues are divided by ``(lambda_r + shift)^p``.

    Parameters
    ----------
    omega : ndarray, shape (N,)
        Angular frequencies (rad/s), positive.
    power : int
        ``p``: 0 receptance, 1 mobility, 2 accelerance.
    shift : float
        An exponential window's decay (1/s): a windowed accelerance is the windowed
        receptance times ``(j w + shift)^2``, the factor evaluated where the window
        moved the poles to.

    Returns
    -------
    ndarray, shape (N,), complex
    """
    if power not in (0, 1, 2):
        raise ValueError(f"power must be 0, 1 or 2, got {power!r}")
    return (1j * np.asarray(omega, dtype=float) + float(shift)) ** power


def normalised_error(H: np.ndarray, S: np.ndarray) -> np.ndarray:
    """``sum |H - S|^2 / sum |H|^2`` over the lines (axis 0), per channel; NaN where the
    measured channel is all zero."""
    num = np.sum(np.abs(np.asarray(H) - np.asarray(S)) ** 2, axis=0)
    den = np.sum(np.abs(np.asarray(H)) ** 2, axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / np.where(den > 0, den, 1.0), np.nan)


def modal_poles(frequency_hz: np.ndarray, damping_ratio: np.ndarray) -> np.ndarray:
    """Continuous-time poles ``-zeta w + j w sqrt(1 - zeta^2)`` of modes (``w = 2 pi f``)."""
    w = 2.0 * np.pi * np.asarray(frequency_hz, dtype=float)
    z = np.clip(np.asarray(damping_ratio, dtype=float), -0.999999, 0.999999)
    return -z * w + 1j * w * np.sqrt(1.0 - z**2)
