"""What one identification gives: the modes, every bootstrap pole and the run's facts."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from automodal import __version__

if TYPE_CHECKING:
    from automodal.core.subspace import StateSpaceModel


@dataclass
class IdentifiedMode:
    """One reported mode: a cluster (or one member rank of a near-repeated cluster)."""

    id: int
    frequency_hz: float
    frequency_std_hz: float
    frequency_ci95_hz: tuple[float, float]
    damping_ratio: float
    damping_std: float
    damping_ci95: tuple[float, float]
    physicalness: float
    physical: bool
    n_members: int
    mode_shape: np.ndarray
    mode_shape_std: np.ndarray
    mpc: float
    cluster: int
    cluster_dim: int
    features: dict[str, float]


@dataclass
class PoleTable:
    """Every bootstrap pole, for plots: cluster ``-1`` is the Trashbox."""

    frequency_hz: np.ndarray
    damping_ratio: np.ndarray
    cluster: np.ndarray
    replicate: np.ndarray

    @classmethod
    def from_poles(
        cls, poles: np.ndarray, cluster: np.ndarray, replicate: np.ndarray
    ) -> PoleTable:
        """The table of continuous-time ``poles`` (rad/s) with their labels."""
        wn = np.abs(poles)
        return cls(
            frequency_hz=wn / (2 * np.pi),
            damping_ratio=-poles.real / np.where(wn > 0, wn, 1.0),
            cluster=cluster,
            replicate=replicate,
        )


@dataclass
class Result:
    """The outcome of one run of the pipeline."""

    modes: list[IdentifiedMode]
    trashbox_members: int
    n_clusters: int
    settings: dict[str, Any]
    warnings: list[str]
    poles: PoleTable
    band_hz: tuple[float, float]
    orders: dict[str, Any]
    """The order scan and the reference model: ``scanned``, ``misfit``, ``n0``,
    ``reference``, ``block_rows``, ``basis``, ``bilinear_T``, ``replicates_on_qr_path``
    and ``reference_path`` (``"gram"`` or ``"qr"``, how the reference model's subspace
    was computed); the report copies it into ``settings.orders``."""
    runtime_s: float
    automodal_version: str = __version__
    reference_model: StateSpaceModel | None = field(default=None, repr=False)
    reciprocity: bool = False
    shape_channels: list[str] = field(default_factory=list)
    n_lines: int = 0
    frf_fit: tuple[np.ndarray, np.ndarray, np.ndarray] | None = field(default=None, repr=False)
    """``(frequency_hz, measured, synthesized)`` over the analysed band, in the input's
    orientation (lines x outputs x inputs); synthesized from the physical modes."""

    @property
    def physical_modes(self) -> list[IdentifiedMode]:
        """The modes called physical."""
        return [m for m in self.modes if m.physical]
