"""The stabilization diagram: poles of the models of increasing order, and which are stable.

A pole of order ``n`` is compared with the poles of the previous scanned order: its
nearest neighbour in frequency there is its predecessor, and it is *stable* in
frequency, damping and shape when each differs from the predecessor's by less than the
tolerances below. Poles that stay put as the order grows are the ones an engineer reads
as modes; poles that wander are noise or computational poles.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from automodal.core.modal import mac, modes_of_eigen
from automodal.core.pole_map import PoleMap

FREQUENCY_TOLERANCE = 0.01
"""Largest relative frequency change of a stable pole (1 %, the usual choice of commercial
stabilization diagrams; a mode's frequency is the best determined of its parameters)."""

DAMPING_TOLERANCE = 0.05
"""Largest relative damping change of a stable pole (5 %: damping is determined an order of
magnitude less well than frequency)."""

MAC_TOLERANCE = 0.98
"""Smallest MAC between a stable pole's shape and its predecessor's."""

STABLE_FREQUENCY, STABLE_DAMPING, STABLE_SHAPE = 1, 2, 4
"""Bits of :attr:`StabilizationPoles.stability`; ``7`` is stable in all three."""
STABLE_ALL = STABLE_FREQUENCY | STABLE_DAMPING | STABLE_SHAPE


@dataclass
class StabilizationPoles:
    """The poles of every scanned order, with their stability against the previous order.

    Attributes
    ----------
    order : ndarray of int, shape (m,)
        Model order of each pole.
    frequency_hz, damping_ratio : ndarray, shape (m,)
        The pole's natural frequency and damping ratio.
    stability : ndarray of int, shape (m,)
        Bits: :data:`STABLE_FREQUENCY`, :data:`STABLE_DAMPING`, :data:`STABLE_SHAPE`
        (0: a new pole, or one of the first order).
    """

    order: np.ndarray
    frequency_hz: np.ndarray
    damping_ratio: np.ndarray
    stability: np.ndarray

    @classmethod
    def empty(cls) -> StabilizationPoles:
        """A diagram without poles."""
        return cls(np.zeros(0, int), np.zeros(0), np.zeros(0), np.zeros(0, int))

    def __len__(self) -> int:
        return int(self.order.size)


def stabilization_poles(
    models: Sequence[tuple[int, np.ndarray, np.ndarray]],
    T: float,
    band_hz: tuple[float, float],
    zeta_max: float,
    pole_map: PoleMap | None = None,
) -> StabilizationPoles:
    """The poles of the scan's models in the band, and their stability.

    Parameters
    ----------
    models : sequence of (n, mu, C V)
        Eigenvalues of the discrete-time state matrix and output-side eigenvectors of the
        models of increasing order ``n`` (what :func:`automodal.core.order.misfit_scan`
        keeps).
    T : float
        Bilinear scale of the models.
    band_hz : (float, float)
        Poles with natural frequencies outside are left out.
    zeta_max : float
        Poles damped more than this (or not at all: ``zeta <= 0``) are left out.
    pole_map : PoleMap, optional
        From the models' poles to the structure's, as for the reported modes.

    Returns
    -------
    StabilizationPoles
        In the order of ``models``, each order's poles by frequency.
    """
    lo, hi = band_hz
    cols: list[tuple[np.ndarray, ...]] = []
    prev: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    for n, mu, CV in models:
        modes = modes_of_eigen(mu, CV, T)
        lam = modes.poles if pole_map is None else pole_map(modes.poles)
        f = np.abs(lam) / (2.0 * np.pi)
        zeta = -lam.real / np.where(np.abs(lam) > 0, np.abs(lam), 1.0)
        keep = (f >= lo) & (f <= hi) & (zeta > 0) & (zeta <= zeta_max)
        f, zeta, shapes = f[keep], zeta[keep], modes.shapes[:, keep]
        flags = np.zeros(f.size, dtype=int)
        if prev is not None and prev[0].size and f.size:
            flags = stability_flags(f, zeta, shapes, *prev)
        cols.append((np.full(f.size, int(n)), f, zeta, flags))
        prev = (f, zeta, shapes)
    if not cols:
        return StabilizationPoles.empty()
    order, f, zeta, flags = (np.concatenate(c) for c in zip(*cols))
    return StabilizationPoles(order=order.astype(int), frequency_hz=f, damping_ratio=zeta,
                              stability=flags.astype(int))


def stable_frequencies(
    models: Sequence[tuple[int, np.ndarray, np.ndarray]],
    T: float,
    band_hz: tuple[float, float],
    zeta_max: float,
    pole_map: PoleMap | None = None,
) -> np.ndarray:
    """Natural frequencies (Hz) of the largest model's poles that are stable in frequency
    and damping against the model before it: where a model of the band sees modes, the
    wandering poles of noise left out. Empty with fewer than two models.

    On the dense grids of family seed 252 (26-40 true modes, 20-40 outputs) their count was
    within one of the true number of modes in the band where the magnitude had 4-17 peaks;
    poles stable in frequency alone were 10-70 % more (in a dense band a noise pole often
    lies within 1 % of some pole of the model before)."""
    if len(models) < 2:
        return np.zeros(0)
    st = stabilization_poles(models[-2:], T, band_hz, zeta_max, pole_map)
    both = STABLE_FREQUENCY | STABLE_DAMPING
    top = (st.order == int(models[-1][0])) & (st.stability & both == both)
    return np.sort(st.frequency_hz[top])


def stability_flags(
    f: np.ndarray,
    zeta: np.ndarray,
    shapes: np.ndarray,
    f_prev: np.ndarray,
    zeta_prev: np.ndarray,
    shapes_prev: np.ndarray,
) -> np.ndarray:
    """Stability bits of poles against their nearest-frequency predecessors.

    Parameters
    ----------
    f, zeta : ndarray, shape (m,)
        Frequencies and damping ratios of this order's poles.
    shapes : ndarray, shape (ny, m)
        Their shapes.
    f_prev, zeta_prev, shapes_prev
        The same for the previous order (at least one pole).

    Returns
    -------
    ndarray of int, shape (m,)
        :data:`STABLE_FREQUENCY` when ``|f - f'| <= FREQUENCY_TOLERANCE f'``,
        :data:`STABLE_DAMPING` when ``|zeta - zeta'| <= DAMPING_TOLERANCE zeta'``,
        :data:`STABLE_SHAPE` when ``MAC >= MAC_TOLERANCE``, with ``'`` the predecessor.
    """
    k = np.argmin(np.abs(f[:, None] - f_prev[None, :]), axis=1)
    fp, zp = f_prev[k], zeta_prev[k]
    m = mac(shapes, shapes_prev)[np.arange(f.size), k]
    out = np.where(np.abs(f - fp) <= FREQUENCY_TOLERANCE * fp, STABLE_FREQUENCY, 0)
    out |= np.where(np.abs(zeta - zp) <= DAMPING_TOLERANCE * zp, STABLE_DAMPING, 0)
    out |= np.where(m >= MAC_TOLERANCE, STABLE_SHAPE, 0)
    return out.astype(int)
