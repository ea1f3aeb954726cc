"""What one identification gives: the modes, every bootstrap pole and the run's facts."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from automodal import __version__

if TYPE_CHECKING:
    from automodal.core.stabilization import StabilizationPoles
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
    reference_mode: int = -1
    """Index of the reference model's mode (in :meth:`ModalModel.modes` order) this mode
    is represented by (internal: not in the report)."""
    mode_number: int | None = None
    """The physical modes numbered 1, 2, ... by frequency (what the table, the figures and
    monitoring call "mode 2"); ``None`` for a cluster not called physical. ``id`` numbers
    every listed cluster."""
    estimator: str = "bootstrap"
    """Where the frequency, damping and their intervals come from: ``"bootstrap"`` (the
    replicates' median and percentiles) or ``"ml"`` (the noise-weighted maximum-likelihood
    refinement of the pole and its Cramér-Rao interval, :mod:`automodal.core.refine`)."""


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
class NoiseInfo:
    """The noise model the run used (:class:`automodal.core.noise.NoiseEstimate` in brief).

    Attributes
    ----------
    source : str
        ``"records"``, ``"coherence"`` or ``"data"``.
    output_level : dict of str to float
        Relative noise level per output channel (noise std over the FRF's RMS).
    n_averages : float or None
        Averages used by the coherence law.
    assumptions : list of str
        What the estimate assumed, in words.
    dispersion : float
        The reference model's whitened residual over its degrees of freedom (at least 1):
        how much more than the noise the model leaves unexplained; SNRs are divided by it.
    """

    source: str
    output_level: dict[str, float]
    n_averages: float | None = None
    assumptions: list[str] = field(default_factory=list)
    dispersion: float = 1.0

    @classmethod
    def from_estimate(
        cls, estimate: Any, output_names: list[str], dispersion: float = 1.0
    ) -> NoiseInfo:
        """From a :class:`~automodal.core.noise.NoiseEstimate` of the FRF (outputs in the
        file's order)."""
        level = np.asarray(estimate.output_level, dtype=float)
        names = output_names if len(output_names) == level.size else [
            f"output {i + 1}" for i in range(level.size)]
        return cls(source=str(estimate.source),
                   output_level=dict(zip(unique_labels(names), map(float, level))),
                   n_averages=estimate.n_averages, assumptions=list(estimate.assumptions),
                   dispersion=float(dispersion))

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form."""
        return {"source": self.source, "output_level": dict(self.output_level),
                "n_averages": self.n_averages, "assumptions": list(self.assumptions),
                "dispersion": self.dispersion}


def unique_labels(names: list[str]) -> list[str]:
    """Channel names as keys: a name that occurs more than once is followed by ``" #k"``,
    ``k`` its 1-based position in ``names`` (two outputs named ``acc`` of three become
    ``acc #1`` and ``acc #3``); the others are kept as they are. Files stacked from
    several tests often repeat a sensor's name, and a dict keyed by the bare names kept
    only the last of them."""
    names = [str(n) for n in names]
    seen = Counter(names)
    labels = [f"{n} #{i + 1}" if seen[n] > 1 else n for i, n in enumerate(names)]
    if len(set(labels)) < len(labels):  # a label that is another channel's own name
        # ("acc #1" beside two "acc"): every name followed by its position, which differs
        labels = [f"{n} #{i + 1}" for i, n in enumerate(names)]
    return labels


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
    orientation (lines x outputs x inputs); synthesized from the physical modes' poles
    with residues and upper and lower residuals fitted by least squares."""
    noise: NoiseInfo | None = None
    """The noise model (source and level per output channel), ``None`` when the run did
    not use one (``weighting="envelope"``)."""
    frf_fit_error: np.ndarray | None = field(default=None, repr=False)
    """Normalised error ``sum |H - S|^2 / sum |H|^2`` of the synthesis per channel
    (outputs x inputs, the input's orientation)."""
    stabilization: StabilizationPoles | None = field(default=None, repr=False)
    """The poles of the order scan's models and their stability, for the stabilization
    diagram."""

    @property
    def physical_modes(self) -> list[IdentifiedMode]:
        """The modes called physical."""
        return [m for m in self.modes if m.physical]
