"""The bilinear (Tustin) map between continuous time and the unit circle.

A continuous-time frequency ``w`` (rad/s) is placed on the unit circle at
``z = exp(1j * wd)`` with ``wd = 2 * arctan(w * T / 2)``; a discrete-time model identified
from data placed there is mapped back exactly with :func:`d2c`. The point map is
``z = (1 + s T/2) / (1 - s T/2)``.
"""

from __future__ import annotations

import numpy as np


def default_scale(omega_lo: float, omega_hi: float) -> float:
    """The default bilinear scale ``T = 2 / w_mid`` with ``w_mid = (w_lo + w_hi) / 2``.

    This maps the top of a band that starts near zero to about 0.7 pi on the unit circle
    (``method.md`` section 1: the geometric mean was 4-100x worse).

    Parameters
    ----------
    omega_lo, omega_hi : float
        Band limits in rad/s, ``omega_hi > 0``.

    Returns
    -------
    float
        ``T`` in seconds.
    """
    omega_mid = 0.5 * (float(omega_lo) + float(omega_hi))
    if not omega_mid > 0:
        raise ValueError("the band must contain a positive frequency")
    return 2.0 / omega_mid


def to_unit_circle(omega: np.ndarray, T: float) -> np.ndarray:
    """Map angular frequencies to points on the unit circle, ``z = exp(2j arctan(w T / 2))``.

    Parameters
    ----------
    omega : array_like
        Angular frequencies in rad/s.
    T : float
        Bilinear scale.

    Returns
    -------
    ndarray
        Complex points of modulus one.
    """
    return np.exp(2j * np.arctan(0.5 * T * np.asarray(omega, dtype=float)))


def poles_d2c(mu: np.ndarray, T: float) -> np.ndarray:
    """Continuous-time poles ``s = (2/T) (mu - 1) / (mu + 1)`` of discrete-time poles ``mu``."""
    mu = np.asarray(mu)
    return (2.0 / T) * (mu - 1.0) / (mu + 1.0)


def poles_c2d(s: np.ndarray, T: float) -> np.ndarray:
    """Discrete-time poles ``mu = (1 + s T/2) / (1 - s T/2)`` of continuous-time poles ``s``."""
    s = np.asarray(s)
    return (1.0 + 0.5 * T * s) / (1.0 - 0.5 * T * s)


def d2c(
    A: np.ndarray, B: np.ndarray | None, C: np.ndarray, D: np.ndarray | None, T: float
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray, np.ndarray | None]:
    """Map a discrete-time state-space model back to continuous time.

    With ``M = (I + A)^-1``: ``Ac = (2/T) M (A - I)``, ``Bc = (2/sqrt T) M B``,
    ``Cc = (2/sqrt T) C M``, ``Dc = D - C M B``. ``B`` and ``D`` may be ``None`` (only the
    poles and shapes wanted).

    Parameters
    ----------
    A, B, C, D : ndarray or None
        Discrete-time model.
    T : float
        Bilinear scale used to place the data on the unit circle.

    Returns
    -------
    tuple
        ``(Ac, Bc, Cc, Dc)``, with ``None`` where ``B``/``D`` were ``None``.
    """
    n = A.shape[0]
    eye = np.eye(n)
    lu = np.linalg.solve(eye + A, np.hstack([A - eye] + ([B] if B is not None else [])))
    Ac = (2.0 / T) * lu[:, :n]
    CM = np.linalg.solve((eye + A).T, C.T).T
    Cc = (2.0 / np.sqrt(T)) * CM
    Bc = Dc = None
    if B is not None:
        MB = lu[:, n:]
        Bc = (2.0 / np.sqrt(T)) * MB
        if D is not None:
            Dc = D - C @ MB
    return Ac, Bc, Cc, Dc


def c2d(
    A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, T: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Inverse of :func:`d2c` (used in tests and to place known systems on the circle).

    With ``N = (I - A T/2)^-1``: ``Ad = N (I + A T/2)``, ``Bd = sqrt(T) N B``,
    ``Cd = sqrt(T) C N``, ``Dd = D + (T/2) C N B``.
    """
    n = A.shape[0]
    eye = np.eye(n)
    Nm = np.linalg.inv(eye - 0.5 * T * A)
    Ad = Nm @ (eye + 0.5 * T * A)
    Bd = np.sqrt(T) * Nm @ B
    Cd = np.sqrt(T) * C @ Nm
    Dd = D + 0.5 * T * C @ Nm @ B
    return Ad, Bd, Cd, Dd
