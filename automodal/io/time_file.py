"""Reading and writing the ``/time`` group of the automodal FRF file (``docs/frf-file.md``).

``/time/outputs`` (n_samples, n_outputs) and optionally ``/time/inputs`` (n_samples,
n_inputs) hold raw time series, the attribute ``sample_rate`` (Hz) on ``/time`` their rate.
Channel names come from ``/outputs/name`` and ``/inputs/name`` when present. The reader
refuses a bad file with one :class:`~automodal.errors.InputError` line naming the file: the
file's layout here (with the shared HDF5 helpers and header of :mod:`automodal.io.hdf5` and
:mod:`automodal.io.header`), the values by :class:`~automodal.timedata.TimeSeries` itself.
"""

from __future__ import annotations

import os
from pathlib import Path

import h5py
import numpy as np

from automodal.frfdata import quantity_problem
from automodal.io.atomic import atomic_path, check_free_space
from automodal.io.channels import MIN_SAMPLES
from automodal.io.hdf5 import (
    check_dataset_size,
    dataset,
    group,
    open_hdf5,
    plain,
    string_list,
    write_time_group,
)
from automodal.io.header import free_attributes, read_header, write_header
from automodal.io.refusal import Refused, read_refusing
from automodal.timedata import TimeSeries

__all__ = ["MIN_SAMPLES", "read_time", "write_time"]



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
        than :data:`automodal.io.limits.MAX_VALUES` numbers (refused before it is read).
    """
    return read_refusing(_read, path)


def _read(path: Path, source: str) -> TimeSeries:
    """Open, check and read the ``/time`` group (raises :class:`Refused` on a bad file)."""
    with open_hdf5(path) as f:
        quantity = read_header(f.attrs)
        time = group(f, "time")
        if time is None:
            raise Refused("no /time group: no time series in the file")
        outputs = _samples(time, "outputs", required=True)
        inputs = _samples(time, "inputs", required=False)
        rate = _sample_rate(time)
        attributes = free_attributes(f.attrs)
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
    """Read ``/time/{name}``: real, 2-D (n_samples, n_channels), long enough, no dead
    channel (finite values and equal lengths are :class:`TimeSeries` rules)."""
    label = f"/time/{name}"
    ds = dataset(time, name)
    if ds is None:
        if required:
            raise Refused(f"no {label} dataset in the /time group")
        return None
    if ds.ndim != 2:
        raise Refused(f"{label} must be 2-D (n_samples, n_{name}), but has shape {ds.shape}")
    if ds.dtype.kind not in "fiu":
        raise Refused(f"{label} must hold real numbers, not dtype {ds.dtype}")
    if ds.shape[1] == 0:
        raise Refused(f"{label} has no channel (shape {ds.shape})")
    if ds.shape[0] < MIN_SAMPLES:
        raise Refused(
            f"{label} has {ds.shape[0]} samples, too short: a spectrum needs at least "
            f"{MIN_SAMPLES}"
        )
    check_dataset_size(ds, label)
    values = np.asarray(ds[()], dtype=np.float64)
    dead = np.flatnonzero(np.ptp(values, axis=0) == 0)
    if dead.size:
        raise Refused(
            f"{label} channel(s) {', '.join(str(int(i) + 1) for i in dead)} are constant "
            "(a dead channel has no spectrum)"
        )
    return values


def _sample_rate(time: h5py.Group) -> float:
    """The ``sample_rate`` attribute of ``/time``: one number (Hz; that it is finite and
    > 0 is a :class:`TimeSeries` rule)."""
    if "sample_rate" not in time.attrs:
        raise Refused("the /time group has no sample_rate attribute (Hz)")
    value = plain(time.attrs["sample_rate"])
    if isinstance(value, list) and len(value) == 1:
        value = value[0]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise Refused(f"/time sample_rate must be a number in Hz, not {value!r}")
    return float(value)


def _names(f: h5py.File, side: str, n: int) -> list[str]:
    """``/{side}/name`` when present (one per channel), else the default names."""
    parent = group(f, side)
    ds = None if parent is None else dataset(parent, "name")
    if ds is None:
        return []
    label = f"/{side}/name"
    if ds.ndim != 1 or ds.shape[0] != n:
        raise Refused(f"{label} has shape {ds.shape}, but /time/{side} has {n} channels")
    return string_list(ds, label)


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
    problem = None if quantity is None else quantity_problem(quantity)
    if problem:
        raise ValueError(problem)
    strings = h5py.string_dtype()
    check_free_space(path, (ts.outputs, ts.inputs))
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        write_header(f, ts.attributes, quantity)
        write_time_group(f, ts)
        f.create_dataset("outputs/name", data=np.array(list(ts.output_names), dtype=strings))
        if ts.inputs is not None:
            f.create_dataset("inputs/name", data=np.array(list(ts.input_names), dtype=strings))

