"""The in-memory test object: one test of one structure as frequency response functions."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

QUANTITIES = ("displacement", "velocity", "acceleration")
"""Response quantities an FRF can be given in: receptance, mobility, accelerance."""


@dataclass
class FRFData:
    """Frequency response functions of one test, with channel metadata.

    Attributes
    ----------
    frequency : ndarray, shape (n_freq,)
        Frequency lines in Hz, strictly increasing, finite, >= 0.
    frf : ndarray, shape (n_freq, n_outputs, n_inputs), complex128
        ``frf[k, i, j]`` is response ``i`` per unit force ``j`` at line ``k``.
    quantity : str
        One of :data:`QUANTITIES`.
    coherence : ndarray or None
        Ordinary coherence, same shape as ``frf``, in [0, 1].
    records : ndarray or None, shape (n_records, n_freq, n_outputs, n_inputs)
        Repeated measurements (hits, averages) when kept separately.
    output_names, input_names : list of str
        Channel names (defaults ``y1..``, ``u1..``).
    output_nodes, input_nodes : ndarray of int or None
        Node numbers in a test geometry.
    output_directions, input_directions : list of str or None
        Directions such as ``"+X"``.
    output_xyz : ndarray, shape (n_outputs, 3), or None
        Sensor coordinates.
    attributes : dict
        Free attributes of the file (structure name, date, ...), copied into reports.
    source : str or None
        Where the data came from (a path), for messages and reports.
    """

    frequency: np.ndarray
    frf: np.ndarray
    quantity: str = "displacement"
    coherence: np.ndarray | None = None
    records: np.ndarray | None = None
    output_names: list[str] = field(default_factory=list)
    input_names: list[str] = field(default_factory=list)
    output_nodes: np.ndarray | None = None
    input_nodes: np.ndarray | None = None
    output_directions: list[str] | None = None
    input_directions: list[str] | None = None
    output_xyz: np.ndarray | None = None
    attributes: dict[str, Any] = field(default_factory=dict)
    source: str | None = None

    def __post_init__(self) -> None:
        self.frequency = np.asarray(self.frequency, dtype=float)
        self.frf = np.asarray(self.frf, dtype=complex)
        if not self.output_names:
            self.output_names = [f"y{i + 1}" for i in range(self.n_outputs)]
        if not self.input_names:
            self.input_names = [f"u{j + 1}" for j in range(self.n_inputs)]

    @property
    def n_freq(self) -> int:
        """Number of frequency lines."""
        return int(self.frf.shape[0])

    @property
    def n_outputs(self) -> int:
        """Number of response channels."""
        return int(self.frf.shape[1])

    @property
    def n_inputs(self) -> int:
        """Number of force (reference) channels."""
        return int(self.frf.shape[2])

    @property
    def omega(self) -> np.ndarray:
        """Angular frequencies in rad/s."""
        return 2.0 * np.pi * self.frequency
