"""Damping equalization: the test data model, and the FE modes given the test's damping.

The test data model is the identified modal model of the measured FRFs: the physical modes'
poles with residues (and upper and lower residual terms) fitted by least squares
(:mod:`automodal.core.synthesis`). Its FRF is smooth and can be evaluated anywhere.

An FE model has no damping worth calibrating against, and a resonance peak of the wrong
height or width makes the log-FRF deviation rough and its valley narrow. Damping
equalization (Abrahamsson and Kammer, MSSP 2015) gives both models the same modal damping,
so that only stiffness and mass are left to explain the difference:

- ``"paired"`` (default): each FE mode paired with a test mode (by frequency and by the MAC
  of its residue matrix ``phi(out) phi(in)^T`` with the test mode's) gets that test mode's
  damping ratio; the test model is left as identified. Unpaired FE modes get a fallback ratio.
- ``"common"``: every mode of both models gets one damping ratio ``zeta0`` (the test model's
  poles are moved to it at their natural frequencies, residues kept): the literal scheme of
  the paper, whose metric gets smoother as ``zeta0`` grows.
- ``"none"``: no equalization, for comparison: every FE mode gets the fallback ratio.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from automodal.core import synthesis
from automodal.core.fe_model import UndampedModes
from automodal.core.matching import match
from automodal.core.modal import PoleValues, mac

EQUALIZATIONS = ("paired", "common", "none")
"""The damping equalization schemes (module text)."""

PAIR_FREQUENCY_WEIGHT = 0.5
"""A relative frequency distance of this much costs as much as a MAC of 0 when FE modes
are paired with test modes: the MAC decides, frequency breaks its ties (starts 30-50 % off
in stiffness move frequencies by 15-30 %)."""

PAIR_MAX_SHIFT = 1.0
"""FE and test modes further apart than this share of the test frequency are not paired."""

PAIR_MIN_MAC = 0.3
"""Nor are modes whose residue matrices have a MAC below this."""


@dataclass(frozen=True)
class TestModel(PoleValues):
    """The test data model: poles with residues and residual terms.

    Attributes
    ----------
    poles : ndarray, shape (m,)
        Poles (rad/s, ``Im > 0``) as they are in the data, in the order of the coefficients.
    coefficients : ndarray, shape (2 m + 2, ny * nu)
        Residues of the poles, of their conjugates, then ``U`` and ``L``
        (:attr:`automodal.core.synthesis.FixedPoleFit.coefficients`).
    power : int
        0 receptance, 1 mobility, 2 accelerance.
    shape : tuple of int
        ``(ny, nu)``.
    """

    __test__ = False  # not a pytest class

    poles: np.ndarray
    coefficients: np.ndarray
    power: int
    shape: tuple[int, int]

    def residue_vectors(self) -> np.ndarray:
        """``vec(R_r)`` of every mode, ``(ny * nu, m)``."""
        return self.coefficients[: self.poles.size].T

    def frf(self, omega: np.ndarray, damping: float | None = None) -> np.ndarray:
        """The model's FRF at ``omega`` (rad/s), ``(N, ny, nu)``; with ``damping``, every
        pole moved to that damping ratio at its natural frequency (``"common"``)."""
        poles = self.poles
        if damping is not None:
            poles = synthesis.modal_poles(self.frequency_hz, np.full(poles.size, damping))
        S = synthesis.synthesize(omega, poles, self.coefficients, self.power)
        return S.reshape(-1, *self.shape)


def fit_test_model(
    omega: np.ndarray, H: np.ndarray, poles: np.ndarray, power: int,
    variance: np.ndarray | None = None,
) -> TestModel:
    """The test data model of ``H`` for fixed ``poles`` (least-squares residues).

    Parameters
    ----------
    omega : ndarray, shape (N,)
        Lines (rad/s).
    H : ndarray, shape (N, ny, nu)
        Measured FRF.
    poles : ndarray, shape (m,)
        The physical modes' poles as they are in the data (``Im > 0``).
    power : int
        0 receptance, 1 mobility, 2 accelerance.
    variance : ndarray, shape (N, ny, nu), optional
        The noise variance of ``H``: each entry's residues are then fitted by weighted least
        squares (its lines weighted by ``1 / sigma``), so that the model is as accurate,
        relative to the noise, where the FRF is small as where it is large. Without it,
        the plain least squares of :func:`automodal.core.synthesis.fit_fixed_poles`, whose
        upper residual can swamp a small FRF far from its modes (measured on a 6-DOF
        chain: log errors of 3 nepers at the top of the band, against 0.005 weighted).
    """
    N, ny, nu = H.shape
    if variance is None:
        fit = synthesis.fit_fixed_poles(omega, H, poles, power)
        return TestModel(poles=fit.poles, coefficients=fit.coefficients, power=int(power),
                         shape=(ny, nu))
    lam = np.unique(np.asarray(poles, dtype=complex).ravel())
    basis = synthesis.pole_basis(np.asarray(omega, dtype=float), lam, power, True)
    inv_sigma = 1.0 / np.sqrt(np.asarray(variance, dtype=float).reshape(N, ny * nu))
    rhs = np.asarray(H, dtype=complex).reshape(N, ny * nu) * inv_sigma
    coef = np.empty((basis.shape[1], ny * nu), dtype=complex)
    for e in range(ny * nu):
        A = basis * inv_sigma[:, e : e + 1]
        norms = np.linalg.norm(A, axis=0)
        norms[norms == 0] = 1.0
        coef[:, e] = np.linalg.lstsq(A / norms, rhs[:, e], rcond=None)[0] / norms
    return TestModel(poles=lam, coefficients=coef, power=int(power), shape=(ny, nu))


def pair_modes(fe: UndampedModes, test: TestModel) -> list[tuple[int, int]]:
    """Pairs ``(test index, FE index)`` of test and elastic FE modes, by the MAC of their
    residue matrices and their frequencies (Hungarian assignment,
    :func:`automodal.core.matching.match`)."""
    elastic = np.flatnonzero(fe.omega > 0)
    if elastic.size == 0 or test.poles.size == 0:
        return []
    macs = mac(test.residue_vectors(), fe.residue_vectors()[:, elastic])
    pairs = match(test.frequency_hz, fe.frequency_hz[elastic], macs,
                  frequency_weight=PAIR_FREQUENCY_WEIGHT, max_relative_shift=PAIR_MAX_SHIFT,
                  min_mac=PAIR_MIN_MAC)
    return [(i, int(elastic[j])) for i, j in pairs]


def fe_damping(
    fe: UndampedModes, test: TestModel, scheme: str, fallback: float,
    common: float | None = None,
) -> np.ndarray:
    """The damping ratio of each FE mode under an equalization ``scheme``.

    Parameters
    ----------
    fe : UndampedModes
    test : TestModel
    scheme : {"paired", "common", "none"}
    fallback : float
        The ratio of FE modes no test mode sets.
    common : float, optional
        ``zeta0`` of ``"common"``.
    """
    if scheme not in EQUALIZATIONS:
        raise ValueError(f"equalization must be one of {EQUALIZATIONS}, got {scheme!r}")
    if scheme == "common":
        if common is None:
            raise ValueError("the common equalization needs its damping ratio")
        return np.full(fe.omega.size, float(common))
    zeta = np.full(fe.omega.size, float(fallback))
    if scheme == "paired":
        for i, j in pair_modes(fe, test):
            zeta[j] = test.damping_ratio[i]
    return zeta
