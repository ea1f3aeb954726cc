"""The in-memory time-series test: raw responses (and forces) sampled at one rate.

A :class:`TimeSeries` is what the ``/time`` group of the automodal FRF file holds. The
pipeline's input stage (:func:`automodal.core.from_time.as_frfdata`) turns it into an
:class:`~automodal.frfdata.FRFData` (H1 estimates when forces were measured, half spectra
for output-only data), which the pipeline then identifies. A :class:`TimeSeries` checks
itself when it is made: each broken rule is an :class:`~automodal.errors.InputError` of one
line naming ``source``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from automodal.errors import InputError


@dataclass
class TimeSeries:
    """Sampled responses of one test, with the measured forces when there are any.

    Attributes
    ----------
    outputs : ndarray, shape (n_samples, n_outputs), float
        Response channels, one column per sensor. A 1-D array is taken as one channel.
    inputs : ndarray, shape (n_samples, n_inputs), float, or None
        Measured forces (same samples as ``outputs``); None for output-only (operational)
        data. A 1-D array is taken as one channel.
    sample_rate : float
        Samples per second (Hz), > 0.
    output_names, input_names : list of str
        Channel names (defaults ``y1..``, ``u1..``; no input names without inputs).
    attributes : dict
        Free attributes of the test (structure, date, ``quantity`` of the responses, ...).
    source : str or None
        Where the data came from (a path), for messages and reports.

    Raises
    ------
    InputError
        If the arrays are not numbers, not 1-D or 2-D, have no sample or channel, hold
        non-finite values or samples above :data:`MAX_SAMPLE_MAGNITUDE`, or differ in their
        number of samples, if a name list has the wrong length, or if ``sample_rate`` is not
        a positive finite number.
    """

    outputs: np.ndarray
    inputs: np.ndarray | None = None
    sample_rate: float = 1.0
    output_names: list[str] = field(default_factory=list)
    input_names: list[str] = field(default_factory=list)
    attributes: dict[str, Any] = field(default_factory=dict)
    source: str | None = None

    def __post_init__(self) -> None:
        self.outputs = _as_channels(self.outputs, "outputs", self.source)
        if self.inputs is not None:
            self.inputs = _as_channels(self.inputs, "inputs", self.source)
            if self.inputs.shape[0] != self.outputs.shape[0]:
                raise InputError(f"the inputs have {self.inputs.shape[0]} samples but the "
                                 f"outputs {self.outputs.shape[0]}", self.source)
        try:
            rate = float(self.sample_rate)
        except (TypeError, ValueError):
            rate = float("nan")
        if not (np.isfinite(rate) and rate > 0):
            raise InputError(f"the sample_rate must be a finite number > 0 (Hz), not "
                             f"{self.sample_rate!r}", self.source)
        self.sample_rate = rate
        self.output_names = _names(self.output_names, self.n_outputs, "y", "output",
                                   self.source)
        self.input_names = _names(self.input_names, self.n_inputs, "u", "input", self.source)

    @property
    def n_samples(self) -> int:
        """Number of samples per channel."""
        return int(self.outputs.shape[0])

    @property
    def n_outputs(self) -> int:
        """Number of response channels."""
        return int(self.outputs.shape[1])

    @property
    def n_inputs(self) -> int:
        """Number of force channels (0 for output-only data)."""
        return 0 if self.inputs is None else int(self.inputs.shape[1])

    @property
    def duration(self) -> float:
        """Length of the record in seconds (``n_samples / sample_rate``)."""
        return self.n_samples / self.sample_rate


def _as_channels(values: Any, label: str, source: str | None) -> np.ndarray:
    """``values`` as a finite float array of shape (n_samples, n_channels)."""
    try:
        arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"the {label} must hold real numbers", source) from None
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2:
        raise InputError(f"the {label} must be (n_samples, n_channels), not of shape "
                         f"{arr.shape}", source)
    if arr.shape[0] == 0 or arr.shape[1] == 0:
        raise InputError(f"the {label} have no sample or no channel (shape {arr.shape})",
                         source)
    n_bad = arr.size - int(np.count_nonzero(np.isfinite(arr)))
    if n_bad:
        raise InputError(f"the {label} have {n_bad} non-finite value(s) (NaN or inf)", source)
    peak = float(np.max(np.abs(arr)))
    if peak > MAX_SAMPLE_MAGNITUDE:
        raise InputError(f"the {label} have samples up to {peak:.3g}, above "
                         f"{MAX_SAMPLE_MAGNITUDE:.0e}: their spectra would overflow; give "
                         "them in other units", source)
    return arr


MAX_SAMPLE_MAGNITUDE = 1e100
"""Largest sample magnitude accepted. Spectra sum products of samples over whole records
(up to about 1e8 samples), which must stay far from the overflow at 1.8e308: samples of
1e200 gave infinite H1 estimates, refused later as "non-finite FRFs" of data that had none.
The FRF's own limit is :data:`automodal.core.checks.MAX_MAGNITUDE`; no unit system puts a
measured signal near either."""


def _names(names: list[str], n: int, prefix: str, side: str, source: str | None) -> list[str]:
    """The given channel names (checked to number ``n``), or ``prefix1..prefixn``."""
    if not names:
        return [f"{prefix}{i + 1}" for i in range(n)]
    names = [str(s) for s in names]
    if len(names) != n:
        raise InputError(f"{len(names)} {side} names for {n} {side} channels", source)
    return names
