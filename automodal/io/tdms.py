"""Reading NI TDMS files of samples with npTDMS (the optional extra ``automodal[tdms]``).

Every channel of every group holding numbers is a channel of samples, named by its channel
name (``group/channel`` when two groups have a channel of that name); all must have the
same length. The sample rate is ``1 / wf_increment``, the waveform property NI writes on
each channel (all channels must agree); a channel named like a time (``t``, ``time``,
``Time [s]``) or holding timestamps is a time axis instead, which gives the rate. A file
whose channels carry no ``wf_increment`` and no time axis needs ``--sample-rate``; which
channels are forces is said with ``--forces``. npTDMS is imported only when a ``.tdms``
file is read.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from automodal.errors import InputError
from automodal.io.channels import Channels, rate_from_time, time_axis, time_unit
from automodal.io.limits import check_size
from automodal.io.refusal import describe, read_refusing

__all__ = ["read_tdms"]

MISSING = "reading a .tdms file needs npTDMS: pip install 'automodal[tdms]'"
"""The refusal when npTDMS is not installed."""


def read_tdms(path: str | os.PathLike[str]) -> Channels:
    """Read the channels of samples of a TDMS file.

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    Channels
        Named by the file; the rate from ``wf_increment`` or a time channel, when the
        file carries one.

    Raises
    ------
    InputError
        One line naming the file: npTDMS missing (:data:`MISSING`), not a TDMS file (or a
        damaged one), no channel of numbers, channels of different lengths or increments,
        two time channels, or more than :data:`automodal.io.limits.MAX_VALUES` numbers
        (refused before the data are read).
    """
    return read_refusing(_read_tdms, path)


def _read_tdms(p: Path, source: str) -> Channels:
    try:
        from nptdms import TdmsFile
    except ImportError:
        raise InputError(MISSING, source) from None
    try:
        with TdmsFile.open(os.fspath(p)) as f:
            found = [(g.name, c) for g in f.groups() for c in g.channels() if len(c) > 0]
            check_size(sum(len(c) for _, c in found), "the channels", source)
            channels = [(group, c.name, c[:], dict(c.properties)) for group, c in found]
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - npTDMS raises many kinds on a foreign file
        raise InputError(f"cannot read as a TDMS file: {describe(exc)}", source) from exc
    return _channels(channels)


def _channels(channels: list[tuple[str, str, np.ndarray, dict[str, Any]]]) -> Channels:
    """The channels of the file, its time axis taken out, its rate found."""
    if not channels:
        raise InputError("no channel with data in the TDMS file")
    lengths = {len(data) for _, _, data, _ in channels}
    if len(lengths) > 1:
        shown = ", ".join(map(str, sorted(lengths)))
        raise InputError(f"the channels have different lengths ({shown}): all must be "
                         "sampled together")
    names = [name for _, name, _, _ in channels]
    labels = [f"{group}/{name}" if names.count(name) > 1 else name
              for group, name, _, _ in channels]
    position, keep = time_axis([np.asarray(data).dtype.kind == "M" or time_unit(name) is not None
                                for _, name, data, _ in channels], labels, "the TDMS file")
    for i in keep:
        if np.asarray(channels[i][2]).dtype.kind not in "fiu":
            raise InputError(f"channel {labels[i]!r} holds {np.asarray(channels[i][2]).dtype}, "
                             "not numbers")
    rate, rate_source = _rate([channels[i][3] for i in keep], [labels[i] for i in keep])
    if position is not None:
        where = f"the time channel {labels[position]!r}"
        time_rate = rate_from_time(_seconds(channels[position]), where)
        if rate is not None and abs(time_rate - rate) > 1e-4 * rate:
            raise InputError(f"{where} gives {time_rate:.9g} Hz but {rate_source} {rate:.9g} Hz")
        rate, rate_source = time_rate, where
    samples = np.column_stack([np.asarray(channels[i][2], dtype=np.float64) for i in keep])
    attributes: dict[str, Any] = {"source_format": "TDMS file"}
    units = [str(channels[i][3].get("unit_string", "")) for i in keep]
    if any(units):
        attributes["channel_units"] = ", ".join(f"{labels[i]}: {u or '?'}"
                                                for i, u in zip(keep, units))
    return Channels(samples=samples, names=[labels[i] for i in keep], positions=keep,
                    sample_rate=rate, rate_source=rate_source, attributes=attributes,
                    time_position=position)


def _rate(properties: list[dict[str, Any]], labels: list[str]) -> tuple[float | None, str]:
    """The rate the channels' ``wf_increment`` give (all alike), or None when none has it."""
    steps = [p.get("wf_increment") for p in properties]
    given = [i for i, s in enumerate(steps) if s is not None]
    if not given:
        return None, ""
    if len(given) < len(steps):
        missing = next(labels[i] for i, s in enumerate(steps) if s is None)
        raise InputError(f"channel {missing!r} has no wf_increment but {labels[given[0]]!r} "
                         "has: the channels must all carry their sample interval, or none")
    values = np.array([float(s) for s in steps])
    if not np.all(np.isfinite(values) & (values > 0)):
        raise InputError(f"a wf_increment is not a positive number ({steps})")
    if np.ptp(values) > 1e-9 * values[0]:
        raise InputError("the channels have different wf_increment (sample intervals): all "
                         "must be sampled at one rate")
    return 1.0 / values[0], "the channels' wf_increment"


def _seconds(channel: tuple[str, str, np.ndarray, dict[str, Any]]) -> np.ndarray:
    """A time channel in seconds (timestamps from the first one)."""
    _, name, data, _ = channel
    data = np.asarray(data)
    if data.dtype.kind == "M":
        return (data - data[0]) / np.timedelta64(1, "ns") * 1e-9
    return data.astype(np.float64) * (time_unit(name) or 1.0)
