"""Modal parameters of a state-space model and the correlation measures between modes."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from automodal.core.bilinear import poles_d2c


class PoleValues:
    """``frequency_hz`` and ``damping_ratio`` of a class's continuous-time ``poles``."""

    poles: np.ndarray

    @property
    def frequency_hz(self) -> np.ndarray:
        """Undamped natural frequencies ``|lambda| / 2 pi`` in Hz."""
        return pole_frequency_hz(self.poles)

    @property
    def damping_ratio(self) -> np.ndarray:
        """Damping ratios ``-Re lambda / |lambda|``."""
        return pole_damping_ratio(self.poles)


@dataclass
class ModeSet(PoleValues):
    """The oscillatory modes (one per conjugate pair, ``Im lambda > 0``) of one model.

    Attributes
    ----------
    poles : ndarray, shape (m,)
        Continuous-time poles ``lambda`` (rad/s).
    mu : ndarray, shape (m,)
        The same poles on the unit circle's side of the bilinear map.
    shapes : ndarray, shape (ny, m)
        Complex mode shapes ``C v``, unit 2-norm, largest entry real positive.
    participation : ndarray, shape (m, nu) or None
        Rows of ``V^-1 B`` (modal participation), when ``B`` was given.
    """

    poles: np.ndarray
    mu: np.ndarray
    shapes: np.ndarray
    participation: np.ndarray | None = None

    @property
    def mpc(self) -> np.ndarray:
        """Modal phase collinearity of each shape, in [0, 1]."""
        return mpc(self.shapes)

    def __len__(self) -> int:
        return int(self.poles.size)


def pole_frequency_hz(poles: np.ndarray) -> np.ndarray:
    """Undamped natural frequencies ``|lambda| / 2 pi`` (Hz) of continuous-time poles."""
    return np.abs(poles) / (2.0 * np.pi)


def pole_damping_ratio(poles: np.ndarray) -> np.ndarray:
    """Damping ratios ``-Re lambda / |lambda|`` of continuous-time poles."""
    return -np.real(poles) / np.abs(poles)


def normalise_shapes(psi: np.ndarray) -> np.ndarray:
    """Scale each column to unit 2-norm and rotate it so its largest entry is real positive."""
    psi = np.asarray(psi, dtype=complex)
    norms = np.linalg.norm(psi, axis=0)
    norms[norms == 0] = 1.0
    psi = psi / norms
    idx = np.argmax(np.abs(psi), axis=0)
    ref = psi[idx, np.arange(psi.shape[1])]
    phase = np.where(np.abs(ref) > 0, ref / np.where(np.abs(ref) > 0, np.abs(ref), 1.0), 1.0)
    return psi / phase


def unit_max_shapes(psi: np.ndarray) -> np.ndarray:
    """Scale each column so that its largest-magnitude entry is ``1 + 0j`` (report convention)."""
    psi = np.asarray(psi, dtype=complex)
    idx = np.argmax(np.abs(psi), axis=0)
    cols = np.arange(psi.shape[1])
    ref = psi[idx, cols]
    ref[ref == 0] = 1.0
    out = psi / ref
    out[idx, cols] = 1.0  # exactly, not 1 - 1e-16
    return out


def oscillatory_order(lam: np.ndarray) -> np.ndarray:
    """Indices of the poles with positive imaginary part (one per conjugate pair), sorted
    by natural frequency ``|lambda|``: the modes a :class:`ModeSet` keeps."""
    keep = np.flatnonzero(lam.imag > 0)
    return keep[np.argsort(np.abs(lam[keep]))]


def modes_of_discrete(
    Ad: np.ndarray,
    Cd: np.ndarray,
    T: float,
    Bd: np.ndarray | None = None,
) -> ModeSet:
    """Modes of a discrete-time model identified through the bilinear map.

    The eigenvectors of ``Ad`` are those of the continuous-time ``A`` (a rational function
    of ``Ad``), and ``Cc v`` is a multiple of ``Cd v``, so the shapes come from ``Cd``
    directly. Only poles with positive imaginary part are kept (one per conjugate pair);
    real and unstable poles stay in the set, for the caller to classify.

    Parameters
    ----------
    Ad, Cd : ndarray
        Discrete-time state and output matrices.
    T : float
        Bilinear scale.
    Bd : ndarray, optional
        Input matrix, for the modal participation.

    Returns
    -------
    ModeSet
        Sorted by natural frequency.
    """
    mu, V = np.linalg.eig(Ad)
    modes = modes_of_eigen(mu, Cd @ V, T)
    if Bd is None:
        return modes
    sel = oscillatory_order(poles_d2c(mu, T))
    return replace(modes, participation=np.linalg.solve(V, Bd)[sel])


def modes_of_eigen(mu: np.ndarray, CV: np.ndarray, T: float) -> ModeSet:
    """:func:`modes_of_discrete` (without participation) of a model whose eigenvalues
    ``mu`` and output-side eigenvectors ``CV = Cd V`` are known already."""
    lam = poles_d2c(mu, T)
    sel = oscillatory_order(lam)
    return ModeSet(poles=lam[sel], mu=mu[sel], shapes=normalise_shapes(CV[:, sel]))


def mac(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Modal assurance criterion between the columns of ``a`` and of ``b``.

    Returns
    -------
    ndarray, shape (a.shape[1], b.shape[1])
        ``|a_i^H b_j|^2 / ((a_i^H a_i)(b_j^H b_j))``.
    """
    a = np.atleast_2d(np.asarray(a, dtype=complex).T).T
    b = np.atleast_2d(np.asarray(b, dtype=complex).T).T
    num = np.abs(a.conj().T @ b) ** 2
    den = np.outer(np.sum(np.abs(a) ** 2, axis=0), np.sum(np.abs(b) ** 2, axis=0))
    return num / np.where(den > 0, den, 1.0)


def mpc(psi: np.ndarray) -> np.ndarray:
    """Modal phase collinearity of each column of ``psi`` (1 for a real-normal mode).

    Uses the eigenvalues of the 2x2 covariance of the real and imaginary parts:
    ``MPC = ((l1 - l2) / (l1 + l2))^2``.
    """
    psi = np.asarray(psi, dtype=complex)
    psi = psi.reshape(psi.shape[0], -1)
    sxx = np.sum(psi.real**2, axis=0)
    syy = np.sum(psi.imag**2, axis=0)
    sxy = np.sum(psi.real * psi.imag, axis=0)
    tr = sxx + syy
    disc = np.sqrt((sxx - syy) ** 2 + 4 * sxy**2)
    return np.where(tr > 0, (disc / np.where(tr > 0, tr, 1.0)) ** 2, 0.0)
