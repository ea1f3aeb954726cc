"""Reading and writing the automodal FRF file (HDF5, version 1; see ``docs/frf-file.md``).

The reader checks the file's layout (datasets present, of the right kind, dtype and shape,
not too large to read) with the shared helpers of :mod:`automodal.io.hdf5` and
:mod:`automodal.io.header`; the rules on the values (finite, frequencies >= 0 and strictly
increasing, coherence in [0, 1], ...) are checked by :class:`~automodal.frfdata.FRFData`
itself. Every problem is an :class:`~automodal.errors.InputError` naming the file, in one
line, never a traceback. The writer produces the same layout, atomically.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from automodal.frfdata import FRFData, quantity_problem
from automodal.io.atomic import atomic_path, check_free_space
from automodal.io.hdf5 import (
    check_shape,
    complex_array,
    dataset,
    group,
    int_array,
    open_hdf5,
    real_array,
    string_list,
    write_time_group,
)
from automodal.io.header import (
    FORMAT_NAME,
    FORMAT_VERSION,
    free_attributes,
    read_header,
    write_header,
)
from automodal.io.refusal import Refused, read_refusing
from automodal.timedata import TimeSeries

__all__ = ["FORMAT_NAME", "FORMAT_VERSION", "read_frf", "write_frf"]


# --------------------------------------------------------------------------------- reading


def read_frf(path: str | os.PathLike[str]) -> FRFData:
    """Read an automodal FRF file.

    The file is opened read-only and never modified.

    Parameters
    ----------
    path : str or path-like
        The HDF5 file (``docs/frf-file.md``).

    Returns
    -------
    FRFData
        The FRFs with every optional field the file holds; root attributes other than
        ``format``, ``version`` and ``quantity`` go to ``attributes`` as plain Python values,
        and ``source`` is ``str(path)``.

    Raises
    ------
    InputError
        If the file is missing, not HDF5, truncated or damaged, or breaks the spec in any
        way a reader must refuse (missing or malformed ``/frf`` or ``/frequency``, non-finite
        values, frequencies not strictly increasing or negative, unknown ``quantity``, newer
        ``version``, a ``window_decay_per_s`` attribute that is not a finite number >= 0, a
        ``discrete_sample_rate_hz`` that is not a finite number > 0,
        a dataset of more than :data:`automodal.io.limits.MAX_VALUES` numbers, refused
        before it is read, ...). The message is one line and names the file. Time-series
        input (``/time`` without ``/frf``) is refused too: it is read by
        :func:`automodal.io.time_file.read_time` (and :func:`automodal.io.readers.read_any`).
    """
    return read_refusing(_read, path)


def _read(path: Path, source: str) -> FRFData:
    """Open, check and read the whole file (raises :class:`Refused` on a bad file)."""
    with open_hdf5(path) as f:
        quantity = read_header(f.attrs)
        frf = _read_frf_array(f)
        n_freq, n_outputs, n_inputs = frf.shape
        outputs = _read_channels(f, "outputs", n_outputs)
        inputs = _read_channels(f, "inputs", n_inputs)
        return FRFData(
            frequency=_read_frequency(f, n_freq),
            frf=frf,
            quantity=quantity,
            coherence=_read_coherence(f, frf.shape),
            records=_read_records(f, frf.shape),
            output_names=outputs["name"] or [],
            input_names=inputs["name"] or [],
            output_nodes=outputs["node"],
            input_nodes=inputs["node"],
            output_directions=outputs["direction"],
            input_directions=inputs["direction"],
            output_xyz=_read_xyz(f, n_outputs),
            attributes=_stated_quantity(_checked_attributes(free_attributes(f.attrs)),
                                        "quantity" in f.attrs),
            source=source,
        )


def _stated_quantity(attributes: dict, stated: bool) -> dict:
    """``attributes`` with ``quantity_source`` saying that the quantity was assumed, when
    the file does not state it (as the other readers say; ``docs/frf-file.md``)."""
    if not stated and "quantity_source" not in attributes:
        attributes["quantity_source"] = ("not stated in the FRF file; assumed displacement"
                                         " (receptance)")
    return attributes


def _read_frf_array(f: h5py.File) -> np.ndarray:
    """Read ``/frf``: complex, 3-D, non-empty."""
    ds = dataset(f, "frf")
    if ds is None:
        if "time" in f:
            raise Refused(
                "time-series input (/time) is not supported by this reader (read it with "
                "automodal.io.time_file.read_time); the file needs FRFs in /frf"
            )
        raise Refused("no /frf dataset and no /time group: not an FRF file")
    return complex_array(ds, "/frf", ndim=3, axes="(n_freq, n_outputs, n_inputs)")


def _read_frequency(f: h5py.File, n_freq: int) -> np.ndarray:
    """Read ``/frequency``: 1-D real, one line per FRF line."""
    ds = dataset(f, "frequency")
    if ds is None:
        raise Refused("no /frequency dataset")
    if ds.ndim != 1:
        raise Refused(f"/frequency must be 1-D, but has shape {ds.shape}")
    if ds.size != n_freq:
        raise Refused(
            f"/frequency has {ds.size} lines but /frf has {n_freq} (its first axis)"
        )
    return real_array(ds, "/frequency")


def _read_coherence(f: h5py.File, shape: tuple[int, ...]) -> np.ndarray | None:
    """Read the optional ``/coherence``: real, same shape as ``/frf``."""
    ds = dataset(f, "coherence")
    if ds is None:
        return None
    check_shape(ds.shape, "/coherence", shape, "the shape of /frf")
    return real_array(ds, "/coherence")


def _read_records(f: h5py.File, shape: tuple[int, ...]) -> np.ndarray | None:
    """Read the optional ``/records/frf``: complex, (n_records,) + shape of ``/frf``."""
    records = group(f, "records")
    ds = None if records is None else dataset(records, "frf")
    if ds is None:
        return None
    axes = "(n_records, n_freq, n_outputs, n_inputs)"
    if ds.ndim == 4 and ds.shape[1:] != tuple(shape):
        raise Refused(
            f"/records/frf has shape {ds.shape}, expected (n_records,) + {tuple(shape)} "
            "(the shape of /frf)"
        )
    return complex_array(ds, "/records/frf", ndim=4, axes=axes)


def _read_channels(f: h5py.File, side: str, n: int) -> dict[str, Any]:
    """Read ``/{side}/name``, ``node`` and ``direction``; each is None when absent."""
    channels = group(f, side)
    found: dict[str, Any] = {"name": None, "node": None, "direction": None}
    if channels is None:
        return found
    for key in found:
        ds = dataset(channels, key)
        if ds is None:
            continue
        label = f"/{side}/{key}"
        if ds.ndim != 1 or ds.shape[0] != n:
            raise Refused(f"{label} has shape {ds.shape}, but /frf has {n} {side}")
        found[key] = int_array(ds, label) if key == "node" else string_list(ds, label)
    return found


def _read_xyz(f: h5py.File, n_outputs: int) -> np.ndarray | None:
    """Read the optional ``/outputs/xyz``, shape (n_outputs, 3)."""
    outputs = group(f, "outputs")
    ds = None if outputs is None else dataset(outputs, "xyz")
    if ds is None:
        return None
    check_shape(ds.shape, "/outputs/xyz", (n_outputs, 3), "(n_outputs, 3)")
    return real_array(ds, "/outputs/xyz")


def _checked_attributes(attributes: dict[str, Any]) -> dict[str, Any]:
    """``attributes``, after refusing a ``window_decay_per_s`` (an exponential window's
    decay in 1/s, which the pipeline adds to every pole) that is not a finite number >= 0,
    and a ``discrete_sample_rate_hz`` (the FRFs are spectra of sampled signals) that is
    not a finite number > 0."""
    for name, zero_allowed, unit in (("window_decay_per_s", True, "1/s"),
                                     ("discrete_sample_rate_hz", False, "Hz")):
        value = attributes.get(name)
        if value is not None and (
            isinstance(value, bool) or not isinstance(value, (int, float))
            or not math.isfinite(value) or value < 0 or (value == 0 and not zero_allowed)
        ):
            raise Refused(f"attribute {name} must be a finite number "
                          f"{'>= 0' if zero_allowed else '> 0'} ({unit}), not {value!r}")
    return attributes


# --------------------------------------------------------------------------------- writing


def write_frf(path: str | os.PathLike[str], data: FRFData,
              time: TimeSeries | None = None) -> None:
    """Write ``data`` as an automodal FRF file (version 1), atomically.

    Every optional field of ``data`` that is set is written; ``data.attributes`` become root
    attributes (keys ``format``, ``version`` and ``quantity`` are reserved and skipped).
    :func:`read_frf` gives back an equal object. ``path`` is replaced only once the whole
    file is written.

    Parameters
    ----------
    path : str or path-like
        Where to write (conventionally ``*.h5``).
    data : FRFData
        The test to write.
    time : TimeSeries, optional
        The time records ``data`` was made from, written as the ``/time`` group
        (:func:`automodal.io.hdf5.write_time_group`); their channels must be those of
        ``data`` (its outputs, and its inputs when they were measured), whose names the
        file holds.

    Raises
    ------
    ValueError
        If ``data.quantity`` is not one of :data:`automodal.frfdata.QUANTITIES`, or
        ``time`` has other channels.
    TypeError
        If an attribute value cannot be stored in HDF5.
    """
    problem = quantity_problem(data.quantity)
    if problem:
        raise ValueError(problem)
    if time is not None and (list(time.output_names) != list(data.output_names) or (
            time.inputs is not None and list(time.input_names) != list(data.input_names))):
        raise ValueError("the time records' channels are not the FRFs' channels")
    arrays = (data.frequency, data.frf, data.coherence, data.records,
              None if time is None else time.outputs, None if time is None else time.inputs)
    check_free_space(path, arrays)
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        write_header(f, data.attributes, data.quantity)
        f.create_dataset("frequency", data=np.asarray(data.frequency, dtype=np.float64))
        f.create_dataset("frf", data=np.asarray(data.frf, dtype=np.complex128))
        if data.coherence is not None:
            f.create_dataset("coherence", data=np.asarray(data.coherence, dtype=np.float64))
        if data.records is not None:
            f.create_dataset("records/frf", data=np.asarray(data.records, dtype=np.complex128))
        _write_channels(f, "outputs", data.output_names, data.output_nodes, data.output_directions)
        _write_channels(f, "inputs", data.input_names, data.input_nodes, data.input_directions)
        if data.output_xyz is not None:
            f.create_dataset("outputs/xyz", data=np.asarray(data.output_xyz, dtype=np.float64))
        if time is not None:
            write_time_group(f, time)


def _write_channels(
    f: h5py.File,
    side: str,
    names: list[str],
    nodes: np.ndarray | None,
    directions: list[str] | None,
) -> None:
    """Write ``/{side}/name`` and, when given, ``node`` and ``direction``."""
    strings = h5py.string_dtype()
    if names:
        f.create_dataset(f"{side}/name", data=np.array(list(names), dtype=strings))
    if nodes is not None:
        f.create_dataset(f"{side}/node", data=np.asarray(nodes, dtype=np.int64))
    if directions is not None:
        f.create_dataset(f"{side}/direction", data=np.array(list(directions), dtype=strings))
