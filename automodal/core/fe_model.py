"""A parametrized finite-element model: its matrices, undamped modes and modal FRF.

The parameters ``theta`` scale parts of the nominal matrices,

    K(theta) = K0 + sum_i (theta_i - 1) K_i,      M(theta) = M0 + sum_i (theta_i - 1) M_i,

so ``theta = 1`` is the nominal model and ``theta_i = 1.1`` makes the part ``K_i`` (and/or
``M_i``) 10 % stiffer (heavier). The FRF is the modal superposition of every mode of the
undamped model with a modal damping ratio per mode (what damping equalization sets):

    H(w) = (jw)^p sum_r phi_r(out) phi_r(in)^T / (w_r^2 - w^2 + 2 j zeta_r w_r w),

with mass-normalised ``phi_r``; rigid-body modes (``w_r = 0``) give the mass line ``-1/w^2``.
Pure functions on arrays: no files, no printing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

RIGID_TOLERANCE = 1e-9
"""An eigenvalue ``w_r^2`` below this share of the largest is a rigid-body mode (set to 0)."""


@dataclass(frozen=True)
class ParametrizedModel:
    """An FE model whose stiffness and mass are linear in the parameters.

    Attributes
    ----------
    stiffness, mass : ndarray, shape (n, n)
        Nominal ``K0`` (symmetric, positive semi-definite) and ``M0`` (positive definite).
    stiffness_parts, mass_parts : ndarray, shape (p, n, n)
        ``K_i`` and ``M_i`` of each parameter (zeros for a parameter that does not scale
        that matrix).
    names : tuple of str
        The parameters' names.
    lower, upper : ndarray, shape (p,)
        Bounds of each ``theta_i`` (``0 < lower <= 1 <= upper``).
    outputs, inputs : ndarray of int
        The model DOF (0-based) of each FRF output and input channel.
    damping : float or None
        Modal damping ratio of FE modes that no test mode sets (None: the test's median).
    """

    stiffness: np.ndarray
    mass: np.ndarray
    stiffness_parts: np.ndarray
    mass_parts: np.ndarray
    names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    outputs: np.ndarray
    inputs: np.ndarray
    damping: float | None = None

    @property
    def n_parameters(self) -> int:
        """Number of parameters ``p``."""
        return len(self.names)

    def matrices(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``K(theta)`` and ``M(theta)``."""
        d = np.asarray(theta, dtype=float) - 1.0
        K = self.stiffness + np.tensordot(d, self.stiffness_parts, axes=1)
        M = self.mass + np.tensordot(d, self.mass_parts, axes=1)
        return K, M


@dataclass(frozen=True)
class UndampedModes:
    """Undamped modes of an FE model, sorted by frequency.

    Attributes
    ----------
    omega : ndarray, shape (m,)
        Natural angular frequencies (rad/s); 0 for rigid-body modes.
    at_outputs, at_inputs : ndarray, shape (ny, m) and (nu, m)
        Mass-normalised shapes at the output and input DOFs.
    """

    omega: np.ndarray
    at_outputs: np.ndarray
    at_inputs: np.ndarray

    @property
    def frequency_hz(self) -> np.ndarray:
        """Natural frequencies (Hz)."""
        return self.omega / (2.0 * np.pi)

    def residue_vectors(self) -> np.ndarray:
        """``vec(phi_r(out) phi_r(in)^T)`` of every mode, ``(ny * nu, m)``: what a test
        mode's residue matrix is compared with (MAC)."""
        v = self.at_outputs[:, None, :] * self.at_inputs[None, :, :]
        return v.reshape(-1, self.omega.size)


def undamped_modes(model: ParametrizedModel, theta: np.ndarray) -> UndampedModes:
    """The undamped modes of ``model`` at ``theta`` (generalized symmetric eigenproblem).

    Raises
    ------
    numpy.linalg.LinAlgError
        When ``M(theta)`` is not positive definite.
    """
    K, M = model.matrices(theta)
    lam, phi = scipy.linalg.eigh(K, M)
    top = max(float(np.max(np.abs(lam))), np.finfo(float).tiny)
    lam = np.where(lam < RIGID_TOLERANCE * top, 0.0, lam)
    return UndampedModes(omega=np.sqrt(lam), at_outputs=phi[model.outputs],
                         at_inputs=phi[model.inputs])


def modal_frf(
    modes: UndampedModes, damping: np.ndarray, omega: np.ndarray, power: int = 0
) -> np.ndarray:
    """The FRF by modal superposition (module text), ``(N, ny, nu)``.

    Parameters
    ----------
    modes : UndampedModes
    damping : ndarray, shape (m,)
        Modal damping ratio of each mode.
    omega : ndarray, shape (N,)
        Lines (rad/s), positive.
    power : int
        0 receptance, 1 mobility, 2 accelerance.
    """
    w = np.asarray(omega, dtype=float)[:, None]
    wr = modes.omega[None, :]
    inv = 1.0 / (wr**2 - w**2 + 2j * np.asarray(damping)[None, :] * wr * w)
    H = (inv @ modes.residue_vectors().T).reshape(w.size, *_channels(modes))
    return H * (1j * np.asarray(omega, dtype=float))[:, None, None] ** power


def _channels(modes: UndampedModes) -> tuple[int, int]:
    """``(ny, nu)``."""
    return modes.at_outputs.shape[0], modes.at_inputs.shape[0]
