"""The in-memory test object: one test of one structure as frequency response functions.

An :class:`FRFData` checks itself when it is made (and :meth:`FRFData.validate` checks it
again on demand): the one place where the rules of ``docs/frf-file.md`` on the arrays are
enforced, whatever the data came from (a reader of any format, the time-series analysis,
Python code). Each broken rule has one message, raised as an
:class:`~automodal.errors.InputError` naming ``source``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from automodal.errors import InputError
from automodal.quantities import QUANTITIES


@dataclass
class FRFData:
    """Frequency response functions of one test, with channel metadata.

    Attributes
    ----------
    frequency : ndarray, shape (n_freq,)
        Frequency lines in Hz, strictly increasing, finite, >= 0.
    frf : ndarray, shape (n_freq, n_outputs, n_inputs), complex128
        ``frf[k, i, j]`` is response ``i`` per unit force ``j`` at line ``k``; finite.
    quantity : str
        One of :data:`QUANTITIES`.
    coherence : ndarray or None
        Ordinary coherence, same shape as ``frf``, in [0, 1].
    records : ndarray or None, shape (n_records, n_freq, n_outputs, n_inputs)
        Repeated measurements (hits, averages) when kept separately; finite.
    output_names, input_names : list of str
        Channel names (defaults ``y1..``, ``u1..``), one per channel.
    output_nodes, input_nodes : ndarray of int or None
        Node numbers in a test geometry, one per channel.
    output_directions, input_directions : list of str or None
        Directions such as ``"+X"``, one per channel.
    output_xyz : ndarray, shape (n_outputs, 3), or None
        Sensor coordinates.
    attributes : dict
        Free attributes of the file (structure name, date, ...), copied into reports.
    source : str or None
        Where the data came from (a path), for messages and reports.

    Raises
    ------
    InputError
        When made with data that break a rule above (see :meth:`validate`); the message
        is one line and names ``source``.
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
        self.frequency = _numbers(self.frequency, float, "frequency axis", self.source)
        self.frf = _numbers(self.frf, complex, "FRFs", self.source)
        if self.coherence is not None:
            self.coherence = _numbers(self.coherence, float, "coherence", self.source)
        if self.records is not None:
            self.records = _numbers(self.records, complex, "repeated records", self.source)
        _raise_first(_SHAPE_RULES, self)
        if not self.output_names:
            self.output_names = [f"y{i + 1}" for i in range(self.n_outputs)]
        if not self.input_names:
            self.input_names = [f"u{j + 1}" for j in range(self.n_inputs)]
        _raise_first(_VALUE_RULES, self)

    def validate(self) -> None:
        """Check every rule again (the arrays may have been changed in place).

        A few vectorised passes over the arrays; made objects are valid, so a caller needs
        this only for data it did not make itself.

        Raises
        ------
        InputError
            One line naming ``source``, for the first broken rule: the frequency axis not
            1-D or empty, with non-finite, negative or not strictly increasing lines; the
            FRFs not 3-D with one line per frequency, empty, or not finite; coherence or
            records of another shape than the FRFs (records with one more, first, axis),
            coherence outside [0, 1] or 0 everywhere, records not finite or not on the
            FRFs' scale; names, nodes, directions or coordinates not one per channel,
            coordinates not finite; an unknown quantity.
        """
        _raise_first(_SHAPE_RULES + _VALUE_RULES, self)

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
    def output_only(self) -> bool:
        """Whether the data are the half spectra of output-only records (attribute
        ``analysis = "operational"``): the references stand for the inputs, and no force
        was measured."""
        return self.attributes.get("analysis") == "operational"

    @property
    def omega(self) -> np.ndarray:
        """Angular frequencies in rad/s."""
        return 2.0 * np.pi * self.frequency


def quantity_problem(quantity: Any) -> str | None:
    """Why ``quantity`` is not a response quantity, or None when it is one of
    :data:`QUANTITIES` (the one message for an unknown quantity, readers included).

    Parameters
    ----------
    quantity : Any

    Returns
    -------
    str or None
    """
    if quantity in QUANTITIES:
        return None
    return f"unknown quantity {quantity!r} (expected one of {', '.join(QUANTITIES)})"


# ---------------------------------------------------------------------------------- rules

Rule = Callable[[FRFData], "str | None"]


def _raise_first(rules: Sequence[Rule], data: FRFData) -> None:
    """Raise the first problem that one of ``rules`` finds in ``data``."""
    for rule in rules:
        problem = rule(data)
        if problem:
            raise InputError(problem, data.source)


def _numbers(values: Any, dtype: type, what: str, source: str | None) -> np.ndarray:
    """``values`` as an array of ``dtype`` (no copy when it already is one)."""
    try:
        return np.asarray(values, dtype=dtype)
    except (TypeError, ValueError):
        raise InputError(f"the {what} must hold numbers", source) from None


def _frequency_shape(d: FRFData) -> str | None:
    f = d.frequency
    if f.ndim != 1 or f.size == 0:
        return f"the frequency axis must be 1-D and not empty, not of shape {f.shape}"
    return None


def _frf_shape(d: FRFData) -> str | None:
    H = d.frf
    if H.ndim != 3 or H.shape[0] != d.frequency.size:
        return (f"the FRF array has shape {H.shape}; expected ({d.frequency.size}, n_outputs, "
                "n_inputs) (one line per frequency)")
    if H.size == 0:
        return f"the FRF array is empty (shape {H.shape})"
    return None


def _coherence_shape(d: FRFData) -> str | None:
    if d.coherence is not None and d.coherence.shape != d.frf.shape:
        return (f"the coherence has shape {d.coherence.shape}, expected {d.frf.shape} "
                "(the shape of the FRFs)")
    return None


def _records_shape(d: FRFData) -> str | None:
    R = d.records
    if R is not None and (R.ndim != 4 or R.shape[0] == 0 or R.shape[1:] != d.frf.shape):
        return (f"the repeated records have shape {R.shape}, expected (n_records,) + "
                f"{d.frf.shape} (at least one record of the FRFs' shape)")
    return None


def _frequency_values(d: FRFData) -> str | None:
    f = d.frequency
    n_bad = int(np.count_nonzero(~np.isfinite(f)))
    if n_bad:
        return f"the frequency axis has {n_bad} non-finite value(s) (NaN or inf)"
    if f[0] < 0:
        return f"the frequency axis has negative values (first line {f[0]:g} Hz)"
    bad = np.flatnonzero(np.diff(f) <= 0)
    if bad.size:
        k = int(bad[0]) + 1
        return (f"the frequencies are not strictly increasing (line {k}: {f[k]:g} Hz after "
                f"{f[k - 1]:g} Hz)")
    return None


def _finite(values: np.ndarray | None, what: str) -> str | None:
    """The problem of non-finite ``values`` (NaN or inf in a real or imaginary part)."""
    if values is None:
        return None
    n_bad = values.size - int(np.count_nonzero(np.isfinite(values)))
    return f"the {what} have {n_bad} non-finite value(s) (NaN or inf)" if n_bad else None


def _coherence_values(d: FRFData) -> str | None:
    c = d.coherence
    if c is not None and not np.all((c >= 0.0) & (c <= 1.0)):
        return "the coherence has values outside [0, 1] (or not finite)"
    return None


def _per_channel(d: FRFData) -> str | None:
    """Names, nodes, directions and coordinates: one per channel."""
    for side, n in (("output", d.n_outputs), ("input", d.n_inputs)):
        for what in ("names", "nodes", "directions"):
            values = getattr(d, f"{side}_{what}")
            if values is None:
                continue
            shape = np.shape(values)
            if shape != (n,):
                got = shape[0] if len(shape) == 1 else f"an array of shape {shape} of"
                return f"{got} {side} {what} for {n} {side}(s): one per channel expected"
    if d.output_xyz is not None and np.shape(d.output_xyz) != (d.n_outputs, 3):
        return (f"the output coordinates have shape {np.shape(d.output_xyz)}, expected "
                f"({d.n_outputs}, 3)")
    return None


def _coordinates_finite(d: FRFData) -> str | None:
    xyz = d.output_xyz
    if xyz is None:
        return None
    n_bad = int(np.count_nonzero(~np.isfinite(np.asarray(xyz, dtype=float))))
    if n_bad:
        return (f"the output coordinates have {n_bad} non-finite value(s): give every "
                "sensor's coordinates, or none")
    return None


def _coherence_not_all_zero(d: FRFData) -> str | None:
    """A coherence of 0 says that no response follows the force, which contradicts an FRF
    that is not zero (H1 = S_yu / S_uu is 0 where the coherence is): a placeholder."""
    c = d.coherence
    if c is not None and not np.any(c > 0) and np.any(d.frf != 0):
        return ("the coherence is 0 at every line and entry, which no measured FRF has "
                "(a placeholder?): leave the coherence out")
    return None


RECORD_SCALE_LIMIT = 0.5
""":func:`_records_scale`: records whose mean's median ratio to the FRF is further than this
from 1 are refused. Measurements of ``H`` average to about ``H`` whatever their noise; a
different unit or sign (factors such as 2 pi, 9.81, 1000, -1) moves the ratio by more than
this. (A conjugate does only where the FRF's phase is far from 0 and 180 degrees: not off
the resonances of a lightly damped one.)"""

_SCALE_SAMPLE = 1 << 16
"""Record values at most :func:`_records_scale` reads (the records of evenly spread entries),
so that its cost does not grow with the records."""

_MIN_SCALE_ENTRIES = 64
"""Entries :func:`_records_scale` takes at least, however many the records."""


def _records_scale(d: FRFData) -> str | None:
    """Repeated records must be measurements of the FRF: in its units and sign convention.

    Each record is ``X_r = H + E_r`` with an error of mean zero (noise of a random phase,
    ``N_r / U_r`` for the ratio records of H1, or the error of one stretch's half spectra,
    which is not symmetric: a stretch's auto-spectrum is a positive, skewed estimate). So the
    records' mean over ``H`` is ``1 + mean_r E_r / H`` at each line and entry, about 1 and
    symmetric about it across them: its median's real and imaginary parts are 1 and 0,
    however noisy or skewed the records. (The median of every record's own ratio, used
    before, is not: on the Weimar frame's setup 1, ``shared/realdata``, the 48 stretches'
    half spectra had a median ratio of 0.43 to their mean, and the rule refused the test's
    own time record.) The entries are evenly spread, with a stride that visits every
    channel, and read from the records without copying them."""
    R = d.records
    if R is None:
        return None
    size = d.frf.size
    k = min(size, max(_MIN_SCALE_ENTRIES, _SCALE_SAMPLE // max(R.shape[0], 1)))
    step = max(1, size // k)
    while step > 1 and math.gcd(step, d.n_outputs * d.n_inputs) != 1:
        step += 1  # a stride that is not a multiple of the entries visits every channel
    flat = np.arange(0, size, step)
    line, out, inp = np.unravel_index(flat, d.frf.shape)
    H = d.frf[line, out, inp]
    ok = np.abs(H) > np.finfo(float).tiny  # a subnormal FRF would give an inf ratio
    if not np.any(ok):
        return None
    X = R[:, line[ok], out[ok], inp[ok]]
    mean = X.mean(axis=0)
    ratio = mean / H[ok]
    c = complex(np.median(ratio.real), np.median(ratio.imag))
    if abs(c - 1.0) > RECORD_SCALE_LIMIT:
        return (f"the repeated records are about {abs(c):.3g} times the FRF at a phase of "
                f"{np.degrees(np.angle(c)):.0f} degrees, so they are not its measurements: "
                "store them in the FRF's units and sign convention, or leave them out")
    if _conjugated(X, mean, H[ok]):
        return ("the repeated records are the complex conjugates of the FRF (the other sign"
                " convention, e^{+i omega t}), so they are not its measurements: store them"
                " in the FRF's convention, or leave them out")
    return None


CONJUGATE_SEPARATION = 6.0
""":func:`_conjugated` judges the entries where ``H`` and its conjugate lie more than this
many standard errors of the records' mean apart."""

MIN_CONJUGATE_ENTRIES = 8
""":func:`_conjugated` says nothing with fewer such entries."""


def _conjugated(X: np.ndarray, mean: np.ndarray, H: np.ndarray) -> bool:
    """Whether records ``X`` (``(n_records, k)`` at ``k`` entries of the FRF ``H``; ``mean``
    their mean) measure ``conj(H)`` rather than ``H``.

    The median ratio of :func:`_records_scale` cannot tell: off the resonances a lightly
    damped FRF is nearly real, and so the ratio of its conjugate to it is nearly 1 (records
    that were the conjugate plus 1 % noise gave 0.98, and the run found no mode and said
    nothing). Where the FRF's imaginary part is large, ``H`` and ``conj(H)`` lie far apart
    against the standard error of the records' mean: there the mean must be nearer ``H``.
    The records are refused when it is nearer ``conj(H)`` at most such entries."""
    n = X.shape[0]
    scale = float(max(np.max(np.abs(X), initial=0.0), np.max(np.abs(H), initial=0.0)))
    if n < 2 or not 0.0 < scale < np.inf:
        return False
    se = scale * np.std(X / scale, axis=0, ddof=1) / np.sqrt(n)  # no overflow near 1e200
    apart = 2.0 * np.abs(H.imag) > CONJUGATE_SEPARATION * se
    if np.count_nonzero(apart) < MIN_CONJUGATE_ENTRIES:
        return False
    m, h = mean[apart], H[apart]
    return bool(np.mean(np.abs(m - np.conj(h)) < np.abs(m - h)) > 0.5)


_SHAPE_RULES: tuple[Rule, ...] = (_frequency_shape, _frf_shape, _coherence_shape,
                                  _records_shape)
"""Rules needed before the channel counts mean anything."""

_VALUE_RULES: tuple[Rule, ...] = (
    _frequency_values,
    lambda d: _finite(d.frf, "FRFs"),
    lambda d: _finite(d.records, "repeated records"),
    _coherence_values,
    _per_channel,
    _coordinates_finite,
    _coherence_not_all_zero,
    _records_scale,
    lambda d: quantity_problem(d.quantity),
)
"""Rules on the values, the channels' metadata and the quantity."""
