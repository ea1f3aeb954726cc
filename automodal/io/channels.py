"""Channels of samples as a file gives them, completed into a :class:`TimeSeries` by what the
user says (``docs/time-input.md``).

A file of raw samples (a NumPy array, a CSV table of samples, a MATLAB file, a TDMS file)
often leaves things unsaid: the sample rate, which channels are forces, the response
quantity. Its reader gives :class:`Channels` (the samples, the channel names, and what the
file does say); :func:`to_time_series` completes them with :class:`TimeOptions` (the
command line's ``--sample-rate``, ``--forces`` and ``--quantity``) and refuses, in one line,
what is missing or contradicts the file:

* the sample rate: the file's (a time column, a rate variable, a channel property) or
  ``--sample-rate``; both given and differing by more than :data:`RATE_TOLERANCE` is
  refused, neither is refused;
* the forces: the file's split (the HDF5 ``/time/inputs``, an NPZ ``inputs`` key, a UFF
  ordinate type) or ``--forces`` (names, or 0-based positions of the channels in the file);
  both must name the same channels; neither means output-only data, unless a channel is
  named like a force (``force``, ``hammer``, ``excitation``), which is refused rather than
  analysed as a response (``--forces none`` says that it is one);
* the quantity: the file's or ``--quantity``; both must agree; neither leaves the FRF file's
  default (displacement, reported as assumed: it labels the FRFs and does not change the
  identified frequencies, damping or shapes).

It also holds what the readers of samples share: recognising a time column by its name
(:func:`time_unit`) and turning a time axis into a sample rate checked to be uniform
(:func:`rate_from_time`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from automodal.errors import InputError
from automodal.frfdata import quantity_problem
from automodal.timedata import TimeSeries

__all__ = [
    "MIN_SAMPLES",
    "RATE_TOLERANCE",
    "Channels",
    "TimeOptions",
    "channels_of",
    "looks_like_force",
    "parse_forces",
    "rate_from_time",
    "time_axis",
    "time_unit",
    "to_time_series",
]

MIN_SAMPLES = 64
"""Fewest samples per channel a time series needs (a spectrum of 33 lines), in every format
(the HDF5 ``/time`` group's reader uses it too)."""

RATE_TOLERANCE = 1e-4
"""Largest relative difference between a sample rate the file carries and ``--sample-rate``
(a time column printed with few digits gives its rate to a few parts per million)."""

UNIFORM_TOLERANCE = 0.1
"""Largest distance, in sample intervals, of a time value from the uniform grid fitted to
all of them (more: a gap or a dropped sample)."""

NO_FORCES = "none"
"""``--forces none``: no channel is a force (output-only data), said explicitly."""

_FORCE_NAME = re.compile(r"force|hammer|excitation", re.IGNORECASE)
_TIME_NAME = re.compile(r"^(t|time)\s*(?:[\[(]?\s*(s|sec|secs|seconds?|ms)\s*[\])]?)?$",
                        re.IGNORECASE)
_TIME_UNITS = {"": 1.0, "s": 1.0, "sec": 1.0, "secs": 1.0, "second": 1.0, "seconds": 1.0,
               "ms": 1e-3}


@dataclass(frozen=True)
class TimeOptions:
    """What the user says about a file of samples (``--sample-rate``, ``--forces``,
    ``--quantity``).

    Attributes
    ----------
    sample_rate : float or None
        Samples per second (Hz), > 0.
    forces : tuple of str, or None
        The force channels, by name or 0-based position in the file; ``()`` says that
        there is none (output-only); None leaves it to the file.
    quantity : str or None
        The response quantity (displacement, velocity or acceleration).

    Raises
    ------
    InputError
        For a sample rate that is not a finite number > 0, an empty force name, or an
        unknown quantity.
    """

    sample_rate: float | None = None
    forces: tuple[str, ...] | None = None
    quantity: str | None = None

    def __post_init__(self) -> None:
        if self.sample_rate is not None:
            rate = float(self.sample_rate)
            if not (np.isfinite(rate) and rate > 0):
                raise InputError(f"--sample-rate must be a finite number > 0 (Hz), not "
                                 f"{self.sample_rate!r}")
            object.__setattr__(self, "sample_rate", rate)
        if self.forces is not None:
            forces = tuple(str(f).strip() for f in self.forces)
            if any(not f for f in forces):
                raise InputError("--forces has an empty channel name (give names or 0-based "
                                 "positions separated by commas, or 'none')")
            object.__setattr__(self, "forces", forces)
        if self.quantity is not None:
            problem = quantity_problem(self.quantity)
            if problem:
                raise InputError(f"--quantity: {problem}")

    @property
    def given(self) -> list[str]:
        """The options that were given, as the command line spells them."""
        names = [("--sample-rate", self.sample_rate), ("--forces", self.forces),
                 ("--quantity", self.quantity)]
        return [name for name, value in names if value is not None]


def parse_forces(text: str | None) -> tuple[str, ...] | None:
    """``--forces`` as :attr:`TimeOptions.forces`: ``"force,2"`` -> ``("force", "2")``,
    ``"none"`` -> ``()``, None -> None."""
    if text is None:
        return None
    if text.strip().lower() == NO_FORCES:
        return ()
    return tuple(part.strip() for part in text.split(","))


@dataclass
class Channels:
    """Named channels of samples and what their file says about them.

    Attributes
    ----------
    samples : ndarray, shape (n_samples, n_channels)
        The channels (not yet checked: :class:`TimeSeries` checks the values).
    names : list of str
        One per channel.
    positions : list of int
        Each channel's 0-based position in the file (a column of a table, a row or column
        of an array), by which ``--forces`` may name it; a time column has a position but
        is no channel.
    sample_rate : float or None
        The rate the file carries (Hz), None when it carries none.
    rate_source : str
        Where the file carries it (for messages and the report).
    forces : list of int or None
        Indices (into ``names``) of the channels the file says are forces; ``[]`` when it
        says there is none; None when it does not say.
    quantity : str or None
        The response quantity the file states.
    attributes : dict
        Free attributes (``source_format`` and what the reader chose).
    time_position : int or None
        Position of the file's time column, when it has one.
    """

    samples: np.ndarray
    names: list[str]
    positions: list[int] = field(default_factory=list)
    sample_rate: float | None = None
    rate_source: str = ""
    forces: list[int] | None = None
    quantity: str | None = None
    attributes: dict[str, Any] = field(default_factory=dict)
    time_position: int | None = None

    def __post_init__(self) -> None:
        if not self.positions:
            self.positions = list(range(len(self.names)))


def channels_of(ts: TimeSeries) -> Channels:
    """The channels of a :class:`TimeSeries` read from a file that states its forces (its
    outputs, then its inputs), its rate and maybe its quantity."""
    samples = ts.outputs if ts.inputs is None else np.hstack([ts.outputs, ts.inputs])
    attributes = dict(ts.attributes)
    quantity = attributes.pop("quantity", None)
    return Channels(samples=samples, names=ts.output_names + ts.input_names,
                    sample_rate=ts.sample_rate, rate_source="the file",
                    forces=list(range(ts.n_outputs, ts.n_outputs + ts.n_inputs)),
                    quantity=quantity, attributes=attributes)


def looks_like_force(name: str) -> bool:
    """Whether a channel's name says it is a force (``force``, ``hammer``, ``excitation``)."""
    return bool(_FORCE_NAME.search(name))


def time_unit(name: str) -> float | None:
    """Seconds per unit of a column named like a time axis, None for another name.

    ``t``, ``time``, ``Time (s)``, ``time [s]``, ``time_s``: 1; ``t [ms]``, ``time_ms``:
    0.001.
    """
    match = _TIME_NAME.match(name.strip().replace("_", " "))
    if not match:
        return None
    return _TIME_UNITS[(match.group(2) or "").lower()]


_OTHER_FREQUENCY_UNIT = re.compile(
    r"(?<![a-z])(khz|mhz|ghz|rad|rpm|cpm|omega)(?![a-z])|/\s*min\b", re.IGNORECASE)
"""Units (or names) of a frequency axis that are not Hz: kHz and larger, rad/s, omega,
revolutions or cycles per minute."""


def frequency_unit_problem(label: str) -> str | None:
    """What is wrong with a frequency axis labelled ``label`` (a column name, a UFF axis
    label), or None: automodal reads frequencies in Hz, and a label naming another unit
    (``frequency (kHz)``, ``freq_kHz``, ``f [rad/s]``, ``omega``, ``rpm``) would otherwise
    be read as Hz, every mode off by that factor."""
    text = label.strip().replace("_", " ")
    if not _OTHER_FREQUENCY_UNIT.search(text):
        return None
    return (f"the frequency axis {label.strip()!r} is not in Hz: automodal reads frequencies"
            " in Hz, so convert them to Hz first")


def time_axis(is_time: list[bool], labels: list[str], what: str) -> tuple[int | None, list[int]]:
    """Which position of a file's columns is its time axis, and which are channels.

    Parameters
    ----------
    is_time : list of bool
        Per column, whether it is a time axis (by its name, its type or its values).
    labels : list of str
        The columns' names, for messages.
    what : str
        What holds them, for messages (``"the table"``).

    Returns
    -------
    position : int or None
        The time axis' position, None without one.
    channels : list of int
        The other positions.

    Raises
    ------
    InputError
        (no file name) For two time axes, or no channel besides the time axis.
    """
    times = [i for i, flag in enumerate(is_time) if flag]
    if len(times) > 1:
        raise InputError(f"{', '.join(repr(labels[i]) for i in times)} of {what} are all time "
                         "axes: keep one")
    channels = [i for i in range(len(is_time)) if i not in times]
    if not channels:
        raise InputError(f"{what} holds only a time axis, no channel")
    return (times[0] if times else None), channels


def rate_from_time(t: np.ndarray, where: str) -> float:
    """The sample rate (Hz) of a time axis in seconds, checked to be uniform.

    Parameters
    ----------
    t : ndarray, 1-D
        The time of each sample, in seconds.
    where : str
        What holds it, for messages (``"the time column 't'"``).

    Returns
    -------
    float
        One over the least-squares time step (robust to times printed with few digits).

    Raises
    ------
    InputError
        (without a file name: the caller's refusal adds it) if the axis has fewer than 2
        values or a non-finite one, does not increase strictly, or strays from the uniform
        grid fitted to it by more than :data:`UNIFORM_TOLERANCE` sample intervals.
    """
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    if t.size < 2 or not np.all(np.isfinite(t)):
        raise InputError(f"{where} must hold at least 2 finite times")
    steps = np.diff(t)
    if np.any(steps <= 0):
        k = int(np.flatnonzero(steps <= 0)[0])
        raise InputError(f"{where} does not increase at sample {k + 1} ({t[k]:.9g} s, then "
                         f"{t[k + 1]:.9g} s)")
    k = np.arange(t.size) - (t.size - 1) / 2.0
    dt = float(np.dot(k, t - t.mean()) / np.dot(k, k))  # least squares: printing round-off
    off = np.abs(t - t.mean() - k * dt) / dt
    worst = int(np.argmax(off))
    if off[worst] > UNIFORM_TOLERANCE:
        raise InputError(f"{where} is not uniformly sampled: sample {worst} is "
                         f"{off[worst]:.2g} sample intervals off the uniform grid (a gap or a "
                         "dropped sample?); resample the record to a uniform rate")
    return 1.0 / dt


# ---------------------------------------------------------------------------- completing


def to_time_series(ch: Channels, options: TimeOptions | None, source: str) -> TimeSeries:
    """Complete the channels of a file into a :class:`TimeSeries` with the user's options.

    Parameters
    ----------
    ch : Channels
        What the reader found.
    options : TimeOptions or None
        What the user says (None: nothing).
    source : str
        The file, for messages and the series' ``source``.

    Returns
    -------
    TimeSeries
        The forces as inputs (None when there is none), the other channels as outputs;
        ``attributes`` say where the sample rate and the split came from
        (``sample_rate_source``, ``forces_source``) and hold the quantity when stated.

    Raises
    ------
    InputError
        One line naming ``source``: see the module's docstring; also for a record shorter
        than :data:`MIN_SAMPLES`, a constant (dead) channel, every channel a force, or
        values that :class:`TimeSeries` refuses (NaN, inf).
    """
    options = options or TimeOptions()
    try:
        rate, rate_source = _rate(ch, options)
        forces, forces_source = _forces(ch, options)
        quantity = _quantity(ch, options)
        _check_samples(ch)
    except InputError as exc:
        raise InputError(exc.problem, source) from None
    responses = [i for i in range(len(ch.names)) if i not in set(forces)]
    if not responses:
        raise InputError("every channel is a force: no response left to analyse", source)
    attributes = dict(ch.attributes)
    attributes["sample_rate_source"] = rate_source
    attributes["forces_source"] = forces_source
    if quantity is not None:
        attributes["quantity"] = quantity
    return TimeSeries(
        outputs=ch.samples[:, responses],
        inputs=ch.samples[:, forces] if forces else None,
        sample_rate=rate,
        output_names=[ch.names[i] for i in responses],
        input_names=[ch.names[i] for i in forces],
        attributes=attributes,
        source=source,
    )


def _rate(ch: Channels, options: TimeOptions) -> tuple[float, str]:
    """The sample rate and where it came from; refuse a missing or contradicted one."""
    given = options.sample_rate
    if ch.sample_rate is None:
        if given is None:
            raise InputError("the file does not carry the sample rate: give it with "
                             "--sample-rate HZ")
        return given, "--sample-rate"
    if given is not None and abs(given - ch.sample_rate) > RATE_TOLERANCE * ch.sample_rate:
        raise InputError(f"--sample-rate {given:g} contradicts the {ch.sample_rate:.9g} Hz of "
                         f"{ch.rate_source}; leave --sample-rate out or correct it")
    return float(ch.sample_rate), ch.rate_source


def _forces(ch: Channels, options: TimeOptions) -> tuple[list[int], str]:
    """Indices of the force channels and where the split came from."""
    if options.forces is not None:
        chosen = [_channel_index(ch, token) for token in options.forces]
        if len(set(chosen)) != len(chosen):
            raise InputError("--forces names a channel twice")
        if ch.forces is not None and set(chosen) != set(ch.forces):
            said = ", ".join(ch.names[i] for i in ch.forces) or "none"
            raise InputError(f"--forces contradicts the file, which says which channels are "
                             f"forces ({said}); leave --forces out")
        return chosen, "--forces"
    if ch.forces is not None:
        return list(ch.forces), "the file"
    named = [name for name in ch.names if looks_like_force(name)]
    if named:
        raise InputError(f"channel {named[0]!r} is named like a force, but the file does not "
                         "say which channels are forces: give --forces (names or 0-based "
                         "positions), or --forces none to analyse every channel as a response")
    return [], "none given: output-only"


def _channel_index(ch: Channels, token: str) -> int:
    """The index of the channel that a ``--forces`` entry names (name or position)."""
    by_name = [i for i, name in enumerate(ch.names) if name == token]
    by_position = ([i for i, p in enumerate(ch.positions) if p == int(token)]
                   if token.isdigit() else [])
    if by_name and by_position and by_name != by_position:
        raise InputError(f"--forces {token!r} is both the name of one channel and the "
                         "position of another; rename the channel")
    found = by_name or by_position
    if len(found) > 1:
        raise InputError(f"--forces {token!r}: several channels have that name")
    if found:
        return found[0]
    if token.isdigit() and ch.time_position == int(token):
        raise InputError(f"--forces {token}: position {token} is the time column, not a "
                         "channel")
    shown = ", ".join(f"{p}:{n}" for p, n in zip(ch.positions[:12], ch.names[:12]))
    more = ", ..." if len(ch.names) > 12 else ""
    raise InputError(f"--forces {token!r} names no channel (position:name are {shown}{more})")


def _quantity(ch: Channels, options: TimeOptions) -> str | None:
    """The response quantity the file or the user states (refuse a contradiction)."""
    stated = ch.quantity
    if stated is not None:
        problem = quantity_problem(stated)
        if problem:
            raise InputError(problem)
    if options.quantity is not None and stated is not None and options.quantity != stated:
        raise InputError(f"--quantity {options.quantity} contradicts the file's {stated}; "
                         "leave --quantity out")
    return stated if stated is not None else options.quantity


def _check_samples(ch: Channels) -> None:
    """Refuse too short a record or a dead channel, naming the channel."""
    n = ch.samples.shape[0] if ch.samples.ndim == 2 else 0
    if n < MIN_SAMPLES:
        raise InputError(f"the record has {n} samples per channel, too short: a spectrum needs "
                         f"at least {MIN_SAMPLES}")
    values = np.asarray(ch.samples, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        dead = np.flatnonzero(np.ptp(values, axis=0) == 0)
    if dead.size:
        raise InputError(f"channel(s) {', '.join(repr(ch.names[i]) for i in dead)} are "
                         "constant (a dead channel has no spectrum)")
