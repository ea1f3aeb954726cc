"""Samples held in arrays: a bare array (``.npy``), or named arrays (``.npz`` members,
MATLAB variables), as :class:`~automodal.io.channels.Channels`.

Orientation: a 2-D array of samples may be (samples, channels) or (channels, samples); the
longer axis is taken as the samples (a record is far longer than it has channels), and a
square array is refused. A 1-D array is one channel.

A time axis among the channels of an array (a channel that increases from its first sample
to its last: no measured signal does) is not a channel: it gives the sample rate (checked
to be uniform, :func:`~automodal.io.channels.rate_from_time`) and keeps its position, so
that ``--forces`` counts positions as they are in the file.

Named arrays (names matched without regard to case, each role at most once):

===================  ===========================================================
role                 names
===================  ===========================================================
samples, unsplit     ``samples``, ``data``, ``signals`` (``--forces`` splits them)
responses / forces   ``outputs`` / ``inputs`` (the file's own split)
sample rate (Hz)     ``sample_rate``, ``fs``, ``samplerate``, ``sampling_rate``
sample interval (s)  ``dt``
time vector (s)      ``time``, ``t``
channel names        ``channel_names``, ``names``; ``output_names``, ``input_names``
quantity             ``quantity``
===================  ===========================================================

Other names are ignored (listed in ``attributes["ignored_keys"]``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from automodal.errors import InputError
from automodal.io.channels import Channels, rate_from_time, time_axis

__all__ = ["ROLES", "TIME_KEYS", "channels_from_array", "channels_from_named", "is_samples_key",
           "samples_first"]

ROLES: dict[str, tuple[str, ...]] = {
    "samples": ("samples", "data", "signals"),
    "outputs": ("outputs",),
    "inputs": ("inputs",),
    "sample_rate": ("sample_rate", "fs", "samplerate", "sampling_rate"),
    "dt": ("dt",),
    "time": ("time", "t"),
    "channel_names": ("channel_names", "names"),
    "output_names": ("output_names",),
    "input_names": ("input_names",),
    "quantity": ("quantity",),
}
"""Each role of a named array and the names that give it."""

TIME_KEYS = ROLES["samples"] + ROLES["outputs"] + ROLES["inputs"]
"""Names that make a container a time-series one."""

LAYOUT = ("expected the samples as 'samples' (or 'data', 'signals'; --forces says which "
          "channels are forces) or as 'outputs' and optionally 'inputs', with the rate as "
          "'sample_rate' (or 'fs'), 'dt' or a time vector 'time' (else --sample-rate), and "
          "optionally 'channel_names' (or 'output_names', 'input_names') and 'quantity'")


def is_samples_key(name: str) -> bool:
    """Whether a member or variable name holds samples (a time-series container)."""
    return name.lower() in TIME_KEYS


def samples_first(values: Any, what: str) -> tuple[np.ndarray, bool]:
    """An array of samples as (samples, channels), and whether it was transposed.

    Raises
    ------
    InputError
        (no file name) For values that are not real numbers, not 1-D or 2-D, or a square
        array (samples cannot be told from channels).
    """
    arr = np.asarray(values)
    if arr.dtype.kind not in "fiu":
        raise InputError(f"{what} must hold real numbers, not dtype {arr.dtype}")
    if arr.ndim == 1:
        return arr.astype(np.float64)[:, None], False
    if arr.ndim != 2:
        raise InputError(f"{what} has shape {arr.shape}; it must be 2-D (samples and "
                         "channels) or 1-D (one channel)")
    rows, cols = arr.shape
    if rows == cols:
        raise InputError(f"{what} is square ({rows} x {cols}): samples cannot be told from "
                         "channels; store it with more samples than channels")
    transposed = cols > rows
    return np.asarray(arr.T if transposed else arr, dtype=np.float64), transposed


def channels_from_array(values: Any, what: str, source_format: str,
                        names: list[str] | None = None) -> Channels:
    """The channels of one array of samples: oriented, its time axis (if any) taken out.

    Parameters
    ----------
    values : array_like
        1-D, or 2-D in either orientation.
    what : str
        What holds it, for messages (``"the array"``, ``"variable 'data'"``).
    source_format : str
        For ``attributes["source_format"]``.
    names : list of str, optional
        One name per channel position (the time axis included); default ``ch0, ch1, ...``.

    Returns
    -------
    Channels
        ``positions`` are the channels' indices along the channel axis; the time axis sets
        ``sample_rate`` and ``time_position``.

    Raises
    ------
    InputError
        (no file name) See :func:`samples_first`; also for several time axes, a time axis
        that is not uniform, an array that is only a time axis, or names of the wrong length.
    """
    samples, transposed = samples_first(values, what)
    n_channels = samples.shape[1]
    if names is not None and len(names) != n_channels:
        raise InputError(f"{len(names)} channel names for the {n_channels} channels of {what}")
    labels = list(names) if names is not None else [f"ch{i}" for i in range(n_channels)]
    attributes: dict[str, Any] = {"source_format": source_format}
    if transposed:
        attributes["orientation"] = "(channels, samples): read with the longer axis as samples"
    rising = [samples.shape[0] > 1 and bool(np.all(np.diff(samples[:, i]) > 0))
              for i in range(n_channels)]
    time_position, keep = time_axis(rising, [f"channel {i}" for i in range(n_channels)],
                                    f"{what} (increasing throughout)")
    rate, rate_source = None, ""
    if time_position is not None:
        where = f"channel {time_position} of {what} (it increases throughout: a time axis)"
        rate, rate_source = rate_from_time(samples[:, time_position], where), where
    return Channels(samples=samples[:, keep], names=[labels[i] for i in keep], positions=keep,
                    sample_rate=rate, rate_source=rate_source, attributes=attributes,
                    time_position=time_position)


def channels_from_named(arrays: dict[str, Any], kind: str, source_format: str,
                        others: Sequence[str] = ()) -> Channels:
    """The channels of a container of named arrays (``.npz`` members, MATLAB variables).

    Parameters
    ----------
    arrays : dict
        Name -> numeric array, ``str`` or list of ``str`` (the caller has turned character
        data into text).
    kind : str
        What the names are called, for messages (``"key"``, ``"variable"``).
    source_format : str
        For ``attributes["source_format"]``.
    others : sequence of str
        Names in the container that were not read (no role): named in messages and in
        ``attributes["ignored_keys"]``.

    Returns
    -------
    Channels

    Raises
    ------
    InputError
        (no file name) For no recognised samples, both forms of samples, two names of one
        role, arrays of the wrong shape or type, names of the wrong length, sample rates
        (a rate, an interval, a time vector, a time axis) that disagree, or a non-text
        quantity.
    """
    found = _roles(arrays, kind)
    get = {role: arrays[name] for role, name in found.items()}
    if "samples" in found and ("outputs" in found or "inputs" in found):
        raise InputError(f"both {found['samples']!r} and {found.get('outputs', 'inputs')!r}: "
                         f"give the samples one way; {LAYOUT}")
    if "samples" in found:
        ch = channels_from_array(get["samples"], f"{kind} {found['samples']!r}", source_format,
                                 _names(get, found, "channel_names", kind))
    elif "outputs" in found:
        ch = _split_channels(get, found, kind, source_format)
    else:
        listed = ", ".join(sorted([*arrays, *others])) or "none"
        raise InputError(f"no samples ({kind}s found: {listed}); {LAYOUT}")
    ignored = sorted((set(arrays) - set(found.values())) | set(others))
    if ignored:
        ch.attributes["ignored_keys"] = ", ".join(ignored)
    _rate_of_named(ch, get, found, kind)
    if "quantity" in found:
        value = get["quantity"]
        if not isinstance(value, str):
            raise InputError(f"{kind} {found['quantity']!r} must be text (displacement, "
                             "velocity or acceleration)")
        ch.quantity = value
    return ch


def _roles(arrays: dict[str, Any], kind: str) -> dict[str, str]:
    """Role -> the container's name for it; refuse two names of one role."""
    found: dict[str, str] = {}
    for role, names in ROLES.items():
        hits = [name for name in arrays if name.lower() in names]
        if len(hits) > 1:
            raise InputError(f"{kind}s {', '.join(map(repr, hits))} both give the {role}; "
                             "keep one")
        if hits:
            found[role] = hits[0]
    return found


def _names(get: dict[str, Any], found: dict[str, str], role: str, kind: str) -> list[str] | None:
    """The channel names of one role, as a list of text (None when absent)."""
    if role not in found:
        return None
    value = get[role]
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise InputError(f"{kind} {found[role]!r} must be a list of channel names (text)")
    return [v.strip() for v in value]


def _split_channels(get: dict[str, Any], found: dict[str, str], kind: str,
                    source_format: str) -> Channels:
    """The file's own split: ``outputs`` and maybe ``inputs`` (the inputs are the forces)."""
    outputs, t_out = samples_first(get["outputs"], f"{kind} {found['outputs']!r}")
    parts, names = [outputs], _names(get, found, "output_names", kind)
    if names is not None and len(names) != outputs.shape[1]:
        raise InputError(f"{len(names)} output names for {outputs.shape[1]} outputs")
    labels = names or [f"y{i + 1}" for i in range(outputs.shape[1])]
    transposed = t_out
    if "inputs" in found:
        inputs, t_in = samples_first(get["inputs"], f"{kind} {found['inputs']!r}")
        if inputs.shape[0] != outputs.shape[0]:
            raise InputError(f"the inputs have {inputs.shape[0]} samples but the outputs "
                             f"{outputs.shape[0]}")
        in_names = _names(get, found, "input_names", kind)
        if in_names is not None and len(in_names) != inputs.shape[1]:
            raise InputError(f"{len(in_names)} input names for {inputs.shape[1]} inputs")
        parts.append(inputs)
        labels += in_names or [f"u{i + 1}" for i in range(inputs.shape[1])]
        transposed = transposed or t_in
    samples = np.hstack(parts)
    attributes: dict[str, Any] = {"source_format": source_format}
    if transposed:
        attributes["orientation"] = "(channels, samples): read with the longer axis as samples"
    n_out = outputs.shape[1]
    return Channels(samples=samples, names=labels, forces=list(range(n_out, samples.shape[1])),
                    attributes=attributes)


def _rate_of_named(ch: Channels, get: dict[str, Any], found: dict[str, str], kind: str) -> None:
    """Set the rate from ``sample_rate``, ``dt`` or ``time``, each agreeing with the others
    and with a time axis among the samples."""
    rates: list[tuple[float, str]] = []
    if ch.sample_rate is not None:
        rates.append((ch.sample_rate, ch.rate_source))
    for role, invert in (("sample_rate", False), ("dt", True)):
        if role in found:
            value = _scalar(get[role], f"{kind} {found[role]!r}")
            rates.append((1.0 / value if invert else value, f"{kind} {found[role]!r}"))
    if "time" in found:
        where = f"the time vector {found['time']!r}"
        t = np.asarray(get["time"])
        if t.dtype.kind not in "fiu" or t.size != ch.samples.shape[0]:
            raise InputError(f"{where} must hold one real time per sample ({ch.samples.shape[0]}"
                             f"), not {t.size} values of dtype {t.dtype}")
        rates.append((rate_from_time(t, where), where))
    if not rates:
        return
    rate, where = rates[0]
    for other, other_where in rates[1:]:
        if abs(other - rate) > 1e-4 * rate:
            raise InputError(f"{other_where} gives {other:.9g} Hz but {where} {rate:.9g} Hz")
    ch.sample_rate, ch.rate_source = rate, where


def _scalar(value: Any, what: str) -> float:
    """One finite positive number (a 1x1 MATLAB matrix included)."""
    arr = np.asarray(value)
    if arr.dtype.kind not in "fiu" or arr.size != 1:
        raise InputError(f"{what} must be one number, not {arr.size} values of dtype {arr.dtype}")
    number = float(arr.reshape(-1)[0])
    if not (np.isfinite(number) and number > 0):
        raise InputError(f"{what} must be a finite number > 0, not {number!r}")
    return number
