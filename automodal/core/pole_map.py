"""From the identified model's poles to the structure's: window decay and sampled spectra.

The identification fits a continuous-time rational model to the data at ``s' = j w'``
(through the bilinear map of :mod:`automodal.core.bilinear`). Two things about the data can
make the structure's poles differ from the model's:

- An exponential window of decay ``a`` (1/s) on the data moved every pole by ``-a``: the
  structure's pole is ``s = s' + a``.
- Spectra of *sampled* signals, such as the half spectra of output-only data
  (:func:`automodal.core.spectra.half_spectra`), are rational in ``z = exp(j w / fs)``,
  not in ``j w``: ``sum_k R(k) z^-k = C (z I - A_d)^-1 G + D`` with the discrete poles
  ``mu = exp(s / fs)``. Treated as a continuous-time FRF they need extra states to absorb
  the difference, and their poles come out biased: on the exact half spectra of a 5-DOF
  chain (0.14-0.2 % damping, ``fs`` = 256 Hz, band to 100 Hz) the lowest mode was not found
  and the second had 15 % too little damping. The Tustin prewarp ``w' = 2 fs tan(w / 2 fs)``
  makes them exactly rational in ``s'`` of the same order (``z = (1 + s'/2fs) / (1 -
  s'/2fs)``), and each pole maps back exactly with ``s = 2 fs artanh(s' / 2 fs)`` (which is
  ``fs log mu``).

Both together: ``s = 2 fs artanh(s' / 2 fs) + a``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["PoleMap"]


@dataclass(frozen=True)
class PoleMap:
    """How the model's continuous-time poles become the structure's.

    Attributes
    ----------
    shift : float
        Decay (1/s) of an exponential window on the data, added back to every pole.
    sample_rate : float or None
        For spectra rational in ``exp(j w / fs)`` (sampled data), ``fs`` in Hz: the lines
        are prewarped for the identification and the poles mapped back. ``None``: the data
        are continuous-time FRFs.
    """

    shift: float = 0.0
    sample_rate: float | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.shift) and self.shift >= 0):
            # an exponential window decays: a negative value is a sign slip, not a window
            raise ValueError(f"the window decay must be finite and >= 0, got {self.shift}")
        if self.sample_rate is not None and not (
            math.isfinite(2.0 * self.sample_rate) and self.sample_rate > 0
        ):  # 2 fs enters the prewarp: it must be a finite number too
            raise ValueError(
                f"the sample rate must be positive and finite, got {self.sample_rate}")

    @property
    def is_identity(self) -> bool:
        """True when the model's poles are the structure's."""
        return self.shift == 0.0 and self.sample_rate is None

    def model_omega(self, omega: np.ndarray) -> np.ndarray:
        """The lines (rad/s) at which the model is fitted: ``omega`` itself, or prewarped
        ``2 fs tan(omega / 2 fs)`` for sampled spectra.

        Raises
        ------
        ValueError
            If a line of sampled spectra is not below the Nyquist frequency ``fs / 2``.
        """
        omega = np.asarray(omega, dtype=float)
        if self.sample_rate is None:
            return omega
        two_fs = 2.0 * self.sample_rate
        if omega.size and not np.max(np.abs(omega)) < np.pi * self.sample_rate:
            raise ValueError(
                f"lines reach {np.max(np.abs(omega)) / (2 * np.pi):.6g} Hz, not below the"
                f" Nyquist frequency {self.sample_rate / 2:.6g} Hz of the sample rate"
            )
        return two_fs * np.tan(omega / two_fs)

    def __call__(self, poles: np.ndarray) -> np.ndarray:
        """The structure's poles of the model's ``poles`` (any shape)."""
        poles = np.asarray(poles)
        if self.sample_rate is not None:
            two_fs = 2.0 * self.sample_rate
            poles = two_fs * np.arctanh(poles / two_fs)
        return poles + self.shift

    def to_model(self, poles: np.ndarray) -> np.ndarray:
        """The model's poles of the structure's ``poles``: the inverse of the map."""
        poles = np.asarray(poles) - self.shift
        if self.sample_rate is not None:
            two_fs = 2.0 * self.sample_rate
            poles = two_fs * np.tanh(poles / two_fs)
        return poles

    def derivative(self, poles: np.ndarray) -> np.ndarray:
        """``ds / ds'`` at the model's ``poles`` (complex, for the intervals)."""
        poles = np.asarray(poles, dtype=complex)
        if self.sample_rate is None:
            return np.ones_like(poles)
        return 1.0 / (1.0 - (poles / (2.0 * self.sample_rate)) ** 2)

    def covariance(self, poles: np.ndarray, cov: np.ndarray) -> np.ndarray:
        """The ``(Re, Im)`` covariances ``cov`` (shape ``(m, 2, 2)``) of the model's poles,
        carried to the structure's poles (the map is conformal: a rotation and a scaling
        by ``ds / ds'``)."""
        g = self.derivative(poles)
        J = np.stack([np.stack([g.real, -g.imag], -1), np.stack([g.imag, g.real], -1)], -2)
        return J @ cov @ np.swapaxes(J, -1, -2)
