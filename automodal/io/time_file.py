"""Reading and writing the ``/time`` group of the automodal FRF file (``spec/frf-file.md``).

``/time/outputs`` (n_samples, n_outputs) and optionally ``/time/inputs`` (n_samples,
n_inputs) hold raw time series, the attribute ``sample_rate`` (Hz) on ``/time`` their rate.
Channel names come from ``/outputs/name`` and ``/inputs/name`` when present. The reader
refuses a bad file with one :class:`~automodal.errors.InputError` line naming the file, in
the style of :mod:`automodal.io.frf_file` (whose checks of the file and its header it
shares).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from automodal.errors import InputError
from automodal.frfdata import QUANTITIES
from automodal.io.atomic import atomic_path
from automodal.io.frf_file import (
    _attribute_value,
    read_refusing,
    FORMAT_NAME,
    FORMAT_VERSION,
    _check_is_file,
    _dataset,
    _free_attributes,
    _group,
    _open_hdf5,
    _plain,
    _read_header,
    _check_size,
    _Refused,
    _string_list,
)
from automodal.timedata import TimeSeries

__all__ = ["MIN_SAMPLES", "read_time", "write_time"]

MIN_SAMPLES = 64
"""Fewest samples per channel a time series needs (a spectrum of 33 lines)."""


# --------------------------------------------------------------------------------- reading


def read_time(path: str | os.PathLike[str]) -> TimeSeries:
    """Read the time series of an automodal FRF file.

    The file is opened read-only and never modified.

    Parameters
    ----------
    path : str or path-like
        The HDF5 file with a ``/time`` group.

    Returns
    -------
    TimeSeries
        Outputs, inputs (None when the file has none: output-only data), ``sample_rate``,
        channel names (defaults ``y1..``/``u1..``), and the root attributes other than
        ``format`` and ``version`` as ``attributes`` (``quantity`` included when the file
        sets it); ``source`` is ``str(path)``.

    Raises
    ------
    InputError
        One line naming the file, if the file is missing, not HDF5 or damaged, has a bad
        header (format, newer version, unknown quantity), no ``/time`` group or no
        ``/time/outputs``, arrays that are not 2-D real (n_samples, n_channels) or hold
        non-finite values, inputs with another number of samples than the outputs, a
        missing or non-positive ``sample_rate``, fewer than :data:`MIN_SAMPLES` samples,
        a constant (dead) channel, channel names of the wrong length, or an array of more
        than :data:`automodal.io.readers.MAX_VALUES` numbers (refused before it is read).
    """
    return read_refusing(_read, path)


def _read(path: Path, source: str) -> TimeSeries:
    """Open, check and read the ``/time`` group (raises :class:`_Refused` on a bad file)."""
    _check_is_file(path)
    with _open_hdf5(path) as f:
        quantity = _read_header(f.attrs)
        time = _group(f, "time")
        if time is None:
            raise _Refused("no /time group: no time series in the file")
        outputs = _samples(time, "outputs", required=True)
        inputs = _samples(time, "inputs", required=False)
        if inputs is not None and inputs.shape[0] != outputs.shape[0]:
            raise _Refused(
                f"/time/inputs has {inputs.shape[0]} samples but /time/outputs "
                f"{outputs.shape[0]}"
            )
        rate = _sample_rate(time)
        attributes = _free_attributes(f.attrs)
        if "quantity" in f.attrs:
            attributes["quantity"] = quantity
        return TimeSeries(
            outputs=outputs,
            inputs=inputs,
            sample_rate=rate,
            output_names=_names(f, "outputs", outputs.shape[1]),
            input_names=[] if inputs is None else _names(f, "inputs", inputs.shape[1]),
            attributes=attributes,
            source=source,
        )


def _samples(time: h5py.Group, name: str, required: bool) -> np.ndarray | None:
    """Read ``/time/{name}``: real, 2-D (n_samples, n_channels), finite, long enough."""
    label = f"/time/{name}"
    ds = _dataset(time, name)
    if ds is None:
        if required:
            raise _Refused(f"no {label} dataset in the /time group")
        return None
    if ds.ndim != 2:
        raise _Refused(f"{label} must be 2-D (n_samples, n_{name}), but has shape {ds.shape}")
    if ds.dtype.kind not in "fiu":
        raise _Refused(f"{label} must hold real numbers, not dtype {ds.dtype}")
    if ds.shape[1] == 0:
        raise _Refused(f"{label} has no channel (shape {ds.shape})")
    if ds.shape[0] < MIN_SAMPLES:
        raise _Refused(
            f"{label} has {ds.shape[0]} samples, too short: a spectrum needs at least "
            f"{MIN_SAMPLES}"
        )
    _check_size(ds, label)
    values = np.asarray(ds[()], dtype=np.float64)
    bad = ~np.isfinite(values)
    if bad.any():
        raise _Refused(f"{label} has {int(bad.sum())} non-finite value(s) (NaN or inf)")
    dead = np.flatnonzero(np.ptp(values, axis=0) == 0)
    if dead.size:
        raise _Refused(
            f"{label} channel(s) {', '.join(str(int(i) + 1) for i in dead)} are constant "
            "(a dead channel has no spectrum)"
        )
    return values


def _sample_rate(time: h5py.Group) -> float:
    """The ``sample_rate`` attribute of ``/time``: one finite number > 0 (Hz)."""
    if "sample_rate" not in time.attrs:
        raise _Refused("the /time group has no sample_rate attribute (Hz)")
    value = _plain(time.attrs["sample_rate"])
    if isinstance(value, list) and len(value) == 1:
        value = value[0]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _Refused(f"/time sample_rate must be a number in Hz, not {value!r}")
    rate = float(value)
    if not (np.isfinite(rate) and rate > 0):
        raise _Refused(f"/time sample_rate must be a finite number > 0, not {rate:g}")
    return rate


def _names(f: h5py.File, side: str, n: int) -> list[str]:
    """``/{side}/name`` when present (one per channel), else the default names."""
    group = _group(f, side)
    ds = None if group is None else _dataset(group, "name")
    if ds is None:
        return []
    label = f"/{side}/name"
    if ds.ndim != 1 or ds.shape[0] != n:
        raise _Refused(f"{label} has shape {ds.shape}, but /time/{side} has {n} channels")
    return _string_list(ds, label)


# --------------------------------------------------------------------------------- writing


def write_time(path: str | os.PathLike[str], ts: TimeSeries) -> None:
    """Write ``ts`` as an automodal file with a ``/time`` group (no ``/frf``), atomically.

    ``ts.attributes`` become root attributes (``format`` and ``version`` are reserved;
    ``quantity`` is written when present). :func:`read_time` gives back an equal object.

    Parameters
    ----------
    path : str or path-like
        Where to write (conventionally ``*.h5``).
    ts : TimeSeries
        The time series.

    Raises
    ------
    ValueError
        If ``ts.attributes["quantity"]`` is not a known quantity.
    TypeError
        If an attribute value cannot be stored in HDF5.
    """
    quantity = ts.attributes.get("quantity")
    if quantity is not None and quantity not in QUANTITIES:
        raise ValueError(f"unknown quantity {quantity!r}")
    strings = h5py.string_dtype()
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs["format"] = FORMAT_NAME
        f.attrs["version"] = FORMAT_VERSION
        for key, value in ts.attributes.items():
            if key not in ("format", "version"):
                f.attrs[key] = _attribute_value(value)
        time = f.create_group("time")
        time.attrs["sample_rate"] = float(ts.sample_rate)
        time.create_dataset("outputs", data=np.asarray(ts.outputs, dtype=np.float64))
        f.create_dataset("outputs/name", data=np.array(list(ts.output_names), dtype=strings))
        if ts.inputs is not None:
            time.create_dataset("inputs", data=np.asarray(ts.inputs, dtype=np.float64))
            f.create_dataset("inputs/name", data=np.array(list(ts.input_names), dtype=strings))
