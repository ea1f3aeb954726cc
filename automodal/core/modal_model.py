"""A discrete-time state-space model in modal form: one eigendecomposition, many uses.

``A = V diag(mu) V^-1`` gives everything the pipeline asks of the reference model: its
oscillatory modes (:class:`~automodal.core.modal.ModeSet`), how much each mode makes of
the FRF at its resonance, the FRF of chosen modes alone, and the MOC vectors of its real
poles. :class:`ModalModel` decomposes ``A`` once (or takes the decomposition the
identification already made) and derives all of them from it.
"""

from __future__ import annotations

import numpy as np

from automodal.core.bilinear import poles_d2c
from automodal.core.correlation import moc_vectors
from automodal.core.modal import ModeSet, normalise_shapes, oscillatory_order
from automodal.core.pole_map import PoleMap
from automodal.core.subspace import StateSpaceModel, modal_sum


class ModalModel:
    """The modes of a discrete-time model ``(A, B, C, D)`` on the bilinear map's circle.

    Parameters
    ----------
    A, B, C, D : ndarray
        Discrete-time model (``B`` and ``D`` may be ``None`` when only modes are needed).
    T : float
        Bilinear scale (continuous-time poles ``lambda = (2 / T)(mu - 1)/(mu + 1)``).
    eigen : (ndarray, ndarray), optional
        ``np.linalg.eig(A)`` if already computed; otherwise computed here, once.

    Attributes
    ----------
    mu : ndarray, shape (n,)
        Eigenvalues of ``A`` (discrete-time poles).
    V : ndarray, shape (n, n)
        Eigenvectors of ``A``.
    poles : ndarray, shape (n,)
        Continuous-time poles of all states.
    oscillatory : ndarray of int
        Indices of the oscillatory modes (``Im lambda > 0``) sorted by natural frequency:
        the modes of :meth:`modes`, which ``keep`` of :meth:`synthesize` indexes.
    """

    def __init__(
        self,
        A: np.ndarray,
        B: np.ndarray | None,
        C: np.ndarray,
        D: np.ndarray | None,
        T: float,
        eigen: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> None:
        self.A, self.B, self.C, self.D, self.T = A, B, C, D, float(T)
        mu, V = np.linalg.eig(A) if eigen is None else eigen
        self.mu: np.ndarray = mu
        self.V: np.ndarray = V
        self.poles: np.ndarray = poles_d2c(mu, T)
        self.oscillatory: np.ndarray = oscillatory_order(self.poles)
        self._modal_inputs: np.ndarray | None = None

    @classmethod
    def from_state_space(cls, model: StateSpaceModel) -> ModalModel:
        """The modal form of an identified model (reusing its ``eigen`` when it has one)."""
        return cls(model.Ad, model.Bd, model.Cd, model.Dd, model.T, eigen=model.eigen)

    @property
    def modal_inputs(self) -> np.ndarray:
        """``V^-1 B``: the modal participation of every state (needs ``B``)."""
        if self.B is None:
            raise ValueError("this model has no B")
        if self._modal_inputs is None:
            self._modal_inputs = np.linalg.solve(self.V, self.B)
        return self._modal_inputs

    def modes(self, pole_map: PoleMap | None = None) -> ModeSet:
        """The oscillatory modes, as :func:`automodal.core.modal.modes_of_discrete` gives
        them for ``(A, C, T, B)``.

        Parameters
        ----------
        pole_map : PoleMap, optional
            From the model's continuous-time poles to the structure's (an exponential
            window's decay, sampled spectra); default none.
        """
        sel = self.oscillatory
        part = None if self.B is None else self.modal_inputs[sel]
        poles = self.poles[sel]
        return ModeSet(
            poles=poles if pole_map is None else pole_map(poles),
            mu=self.mu[sel],
            shapes=normalise_shapes(self.C @ self.V[:, sel]),
            participation=part,
        )

    def frequency_response(self, points: np.ndarray) -> np.ndarray:
        """``D + C (p I - A)^-1 B`` at each point ``p``, shape ``(len(points), ny, nu)``
        (equal to :func:`automodal.core.subspace.frequency_response`)."""
        CV = self.C @ self.V
        return self.D[None] + modal_sum(CV, self.mu, self.modal_inputs, np.asarray(points))

    def contributions(self) -> np.ndarray:
        """How much each oscillatory mode makes of the model's FRF at its own resonance.

        The mode's term ``R / (z - mu)`` (``R = C v l^T``) at the point of the unit circle
        nearest its pole, over the whole model's FRF there (Frobenius norms). A physical
        mode dominates its resonance (about 1); a mode that only fits noise contributes
        little. Zeros when there is no oscillatory mode or no ``B``.

        Returns
        -------
        ndarray, shape (len(self.oscillatory),)
            In the order of :meth:`modes`.
        """
        sel = self.oscillatory
        if sel.size == 0 or self.B is None:
            return np.zeros(sel.size)
        mu = self.mu[sel]
        psi = self.C @ self.V[:, sel]
        resid = np.einsum("ai,ib->iab", psi, self.modal_inputs[sel])  # (m, ny, nu)
        zc = mu / np.abs(mu)
        term = np.linalg.norm(resid, axis=(1, 2)) / np.maximum(np.abs(zc - mu), 1e-300)
        total = np.linalg.norm(self.frequency_response(zc), axis=(1, 2))
        return term / np.maximum(total, 1e-300)

    def synthesize(self, z: np.ndarray, keep: np.ndarray) -> np.ndarray:
        """FRF of the model keeping only some oscillatory modes (and ``D``).

        Parameters
        ----------
        z : ndarray, shape (N,)
            Points on the unit circle.
        keep : ndarray of int
            Indices into :meth:`modes` (sorted by natural frequency). Each kept mode
            contributes its term and its conjugate's, so the result is the FRF of those
            modes alone; keeping every mode of a model with only oscillatory poles gives
            :meth:`frequency_response`.

        Returns
        -------
        ndarray, shape (N, ny, nu)
        """
        H = np.broadcast_to(self.D, (z.size,) + self.D.shape).astype(complex)
        keep = np.asarray(keep, dtype=int)
        if keep.size == 0:
            return H
        sel = self.oscillatory[keep]
        L = self.modal_inputs[sel]
        CV = (self.C @ self.V)[:, sel]
        mu = self.mu[sel]
        # each mode with its conjugate: R / (z - mu) + conj(R) / (z - conj mu)
        return H + modal_sum(CV, mu, L, z) + np.conj(modal_sum(CV, mu, L, z.conj()))

    def real_mode_vectors(self, k: int) -> np.ndarray:
        """MOC vectors (``k`` block rows) of the real (non-oscillatory) poles, shape
        ``(k ny, number of real poles)``."""
        real = self.mu.imag == 0
        if not real.any():
            return np.zeros((k * self.C.shape[0], 0), dtype=complex)
        return moc_vectors(normalise_shapes(self.C @ self.V[:, real]), self.mu[real], k)


def synthesize(
    A: np.ndarray,
    B: np.ndarray,
    C: np.ndarray,
    D: np.ndarray,
    z: np.ndarray,
    keep: np.ndarray,
    T: float = 1.0,
) -> np.ndarray:
    """FRF of ``(A, B, C, D)`` keeping only the oscillatory modes ``keep`` (see
    :meth:`ModalModel.synthesize`; ``T`` only orders the modes, as in
    :func:`automodal.core.modal.modes_of_discrete` with that scale)."""
    return ModalModel(A, B, C, D, T).synthesize(z, keep)
