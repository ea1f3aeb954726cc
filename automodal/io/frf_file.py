"""Reading and writing the automodal FRF file (HDF5, version 1; see ``spec/frf-file.md``).

The reader checks everything the spec says a reader must refuse and reports each problem as
an :class:`~automodal.errors.InputError` naming the file, in one line, never as a traceback.
The writer produces the same layout, atomically.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import h5py
import numpy as np

from automodal.errors import InputError
from automodal.frfdata import QUANTITIES, FRFData
from automodal.io.atomic import atomic_path
from automodal.io.readers import size_problem

__all__ = ["FORMAT_NAME", "FORMAT_VERSION", "read_frf", "write_frf"]

FORMAT_NAME = "automodal-frf"
"""Value of the root attribute ``format``."""

FORMAT_VERSION = 1
"""The newest file version this module reads, and the one it writes."""

_RESERVED_ATTRIBUTES = ("format", "version", "quantity")
_READ_ERRORS = (OSError, RuntimeError, KeyError, ValueError, TypeError)


class _Refused(Exception):
    """A problem with the file; :func:`read_frf` adds the path and raises InputError."""

    def __init__(self, problem: str) -> None:
        super().__init__(problem)
        self.problem = problem


# --------------------------------------------------------------------------------- reading


def read_frf(path: str | os.PathLike[str]) -> FRFData:
    """Read an automodal FRF file.

    The file is opened read-only and never modified.

    Parameters
    ----------
    path : str or path-like
        The HDF5 file (``spec/frf-file.md``).

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
        ``version``, a ``window_decay_per_s`` attribute that is not a finite number >= 0,
        a dataset of more than :data:`automodal.io.readers.MAX_VALUES` numbers, refused
        before it is read, ...). The message is one line and names the file. Time-series
        input (``/time`` without ``/frf``) is refused too: this reader does not support it
        yet.
    """
    return read_refusing(_read, path)


_T = TypeVar("_T")


def read_refusing(read: Callable[[Path, str], _T], path: str | os.PathLike[str]) -> _T:
    """Run ``read(path, source)`` and turn every refusal or read failure into one
    :class:`InputError` naming the file (shared by the FRF and time-series readers)."""
    source = str(path)
    try:
        return read(Path(path), source)
    except _Refused as exc:
        raise InputError(exc.problem, source) from None
    except _READ_ERRORS as exc:
        raise InputError(f"cannot read the file: {_describe(exc)}", source) from exc


def _read(path: Path, source: str) -> FRFData:
    """Open, check and read the whole file (raises :class:`_Refused` on a bad file)."""
    _check_is_file(path)
    with _open_hdf5(path) as f:
        quantity = _read_header(f.attrs)
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
            attributes=_checked_attributes(_free_attributes(f.attrs)),
            source=source,
        )


def _check_is_file(path: Path) -> None:
    """Refuse a missing path or a folder."""
    if not path.exists():
        raise _Refused("no such file")
    if path.is_dir():
        raise _Refused("is a folder, not an FRF file")


def _open_hdf5(path: Path) -> h5py.File:
    """Open ``path`` read-only as HDF5, refusing files that are not HDF5 or are damaged."""
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        if path.stat().st_size == 0:
            raise _Refused("the file is empty (0 bytes), not an HDF5 file") from exc
        if not _looks_like_hdf5(path):
            raise _Refused("not an HDF5 file") from exc
        raise _Refused(f"damaged or truncated HDF5 file: {_describe(exc)}") from exc


def _looks_like_hdf5(path: Path) -> bool:
    """Whether ``path`` carries an HDF5 signature (True when that cannot be told)."""
    try:
        return bool(h5py.is_hdf5(path))
    except _READ_ERRORS:
        return True


def _read_header(attrs: h5py.AttributeManager) -> str:
    """Check the ``format`` and ``version`` attributes and return the ``quantity``."""
    if "format" in attrs:
        fmt = _plain(attrs["format"])
        if fmt != FORMAT_NAME:
            raise _Refused(f"format attribute is {fmt!r}, not {FORMAT_NAME!r}")
    if "version" in attrs:
        _check_version(_plain(attrs["version"]))
    quantity = _plain(attrs["quantity"]) if "quantity" in attrs else "displacement"
    if quantity not in QUANTITIES:
        raise _Refused(f"unknown quantity {quantity!r} (expected one of {', '.join(QUANTITIES)})")
    return quantity


def _check_version(version: Any) -> None:
    """Refuse a version that is not an integer this reader knows."""
    if isinstance(version, float) and version.is_integer():
        version = int(version)  # tools such as MATLAB write numeric attributes as doubles
    if isinstance(version, bool) or not isinstance(version, int):
        raise _Refused(f"version attribute must be an integer, not {version!r}")
    if version > FORMAT_VERSION:
        raise _Refused(
            f"file version {version} is newer than this reader knows ({FORMAT_VERSION}); "
            "update automodal"
        )
    if version < 1:
        raise _Refused(f"unknown file version {version}")


def _read_frf_array(f: h5py.File) -> np.ndarray:
    """Read ``/frf``: complex, 3-D, non-empty, finite."""
    ds = _dataset(f, "frf")
    if ds is None:
        if "time" in f:
            raise _Refused(
                "time-series input (/time) is not supported by this reader yet; "
                "the file needs FRFs in /frf"
            )
        raise _Refused("no /frf dataset and no /time group: not an FRF file")
    return _complex_array(ds, "/frf", ndim=3, axes="(n_freq, n_outputs, n_inputs)")


def _read_frequency(f: h5py.File, n_freq: int) -> np.ndarray:
    """Read ``/frequency``: one finite, non-negative, strictly increasing line per FRF line."""
    ds = _dataset(f, "frequency")
    if ds is None:
        raise _Refused("no /frequency dataset")
    if ds.ndim != 1:
        raise _Refused(f"/frequency must be 1-D, but has shape {ds.shape}")
    if ds.size != n_freq:
        raise _Refused(
            f"/frequency has {ds.size} lines but /frf has {n_freq} (its first axis)"
        )
    freq = _real_array(ds, "/frequency")
    _check_finite(freq, "/frequency")
    if freq[0] < 0:
        raise _Refused(f"/frequency has negative values (first line {freq[0]:g} Hz)")
    _check_increasing(freq)
    return freq


def _check_increasing(freq: np.ndarray) -> None:
    """Refuse frequencies that are not strictly increasing, naming the first bad line."""
    bad = np.flatnonzero(np.diff(freq) <= 0)
    if bad.size:
        k = int(bad[0]) + 1
        raise _Refused(
            f"/frequency is not strictly increasing (line {k}: {freq[k]:g} Hz "
            f"after {freq[k - 1]:g} Hz)"
        )


def _read_coherence(f: h5py.File, shape: tuple[int, ...]) -> np.ndarray | None:
    """Read the optional ``/coherence``: same shape as ``/frf``, values in [0, 1]."""
    ds = _dataset(f, "coherence")
    if ds is None:
        return None
    _check_shape(ds.shape, "/coherence", shape, "the shape of /frf")
    coherence = _real_array(ds, "/coherence")
    if not np.all((coherence >= 0.0) & (coherence <= 1.0)):
        raise _Refused("/coherence has values outside [0, 1] (or not finite)")
    return coherence


def _read_records(f: h5py.File, shape: tuple[int, ...]) -> np.ndarray | None:
    """Read the optional ``/records/frf``: complex, (n_records,) + shape of ``/frf``."""
    group = _group(f, "records")
    ds = None if group is None else _dataset(group, "frf")
    if ds is None:
        return None
    axes = "(n_records, n_freq, n_outputs, n_inputs)"
    if ds.ndim == 4 and ds.shape[1:] != tuple(shape):
        raise _Refused(
            f"/records/frf has shape {ds.shape}, expected (n_records,) + {tuple(shape)} "
            "(the shape of /frf)"
        )
    return _complex_array(ds, "/records/frf", ndim=4, axes=axes)


def _read_channels(f: h5py.File, side: str, n: int) -> dict[str, Any]:
    """Read ``/{side}/name``, ``node`` and ``direction``; each is None when absent."""
    group = _group(f, side)
    found: dict[str, Any] = {"name": None, "node": None, "direction": None}
    if group is None:
        return found
    for key in found:
        ds = _dataset(group, key)
        if ds is None:
            continue
        label = f"/{side}/{key}"
        _check_length(ds, label, n, side)
        found[key] = _int_array(ds, label) if key == "node" else _string_list(ds, label)
    return found


def _read_xyz(f: h5py.File, n_outputs: int) -> np.ndarray | None:
    """Read the optional ``/outputs/xyz``, shape (n_outputs, 3)."""
    group = _group(f, "outputs")
    ds = None if group is None else _dataset(group, "xyz")
    if ds is None:
        return None
    _check_shape(ds.shape, "/outputs/xyz", (n_outputs, 3), "(n_outputs, 3)")
    return _real_array(ds, "/outputs/xyz")


def _free_attributes(attrs: h5py.AttributeManager) -> dict[str, Any]:
    """The root attributes other than format/version/quantity, as plain Python values."""
    return {key: _plain(attrs[key]) for key in attrs if key not in _RESERVED_ATTRIBUTES}


def _checked_attributes(attributes: dict[str, Any]) -> dict[str, Any]:
    """``attributes``, after refusing a ``window_decay_per_s`` (an exponential window's
    decay in 1/s, which the pipeline adds to every pole) that is not a finite number >= 0."""
    decay = attributes.get("window_decay_per_s")
    if decay is not None and (
        isinstance(decay, bool) or not isinstance(decay, (int, float))
        or not math.isfinite(decay) or decay < 0
    ):
        raise _Refused(
            f"attribute window_decay_per_s must be a finite number >= 0 (1/s), not {decay!r}"
        )
    return attributes


# ------------------------------------------------------------------ reading: small checks


def _group(parent: h5py.Group, name: str) -> h5py.Group | None:
    """The group ``name`` under ``parent``, None when absent; refuse anything else there."""
    obj = parent.get(name)
    if obj is not None and not isinstance(obj, h5py.Group):
        raise _Refused(f"{_h5name(parent, name)} must be a group, not a dataset")
    return obj


def _dataset(parent: h5py.Group, name: str) -> h5py.Dataset | None:
    """The dataset ``name`` under ``parent``, None when absent; refuse a group there."""
    obj = parent.get(name)
    if obj is not None and not isinstance(obj, h5py.Dataset):
        raise _Refused(f"{_h5name(parent, name)} must be a dataset, not a group")
    return obj


def _h5name(parent: h5py.Group, name: str) -> str:
    """The absolute HDF5 name of ``name`` under ``parent``."""
    return f"{parent.name.rstrip('/')}/{name}"


def _complex_array(ds: h5py.Dataset, label: str, ndim: int, axes: str) -> np.ndarray:
    """Read a complex dataset of ``ndim`` axes, refusing real, empty or non-finite data."""
    if ds.ndim != ndim:
        raise _Refused(f"{label} must be {ndim}-D {axes}, but has shape {ds.shape}")
    if ds.dtype.kind != "c":
        raise _Refused(
            f"{label} is not complex (dtype {ds.dtype}); real FRFs are refused, "
            "not given zero phase"
        )
    if ds.size == 0:
        raise _Refused(f"{label} is empty (shape {ds.shape})")
    _check_size(ds, label)
    values = np.asarray(ds[()], dtype=np.complex128)
    _check_finite(values, label)
    return values


def _real_array(ds: h5py.Dataset, label: str) -> np.ndarray:
    """Read a dataset of real numbers as float64, refusing other types and empty data."""
    if ds.dtype.kind not in "fiu":
        raise _Refused(f"{label} must hold real numbers, not dtype {ds.dtype}")
    if ds.size == 0:
        raise _Refused(f"{label} is empty (shape {ds.shape})")
    _check_size(ds, label)
    return np.asarray(ds[()], dtype=np.float64)


def _int_array(ds: h5py.Dataset, label: str) -> np.ndarray:
    """Read a dataset of integers as int64."""
    if ds.dtype.kind not in "iu":
        raise _Refused(f"{label} must hold integers, not dtype {ds.dtype}")
    _check_size(ds, label)
    return np.asarray(ds[()], dtype=np.int64)


def _string_list(ds: h5py.Dataset, label: str) -> list[str]:
    """Read a dataset of UTF-8 strings as a list of str."""
    if h5py.check_string_dtype(ds.dtype) is None:
        raise _Refused(f"{label} must hold strings, not dtype {ds.dtype}")
    _check_size(ds, label)
    return [str(s) for s in ds.asstr(errors="replace")[()]]


def _check_size(ds: h5py.Dataset, label: str) -> None:
    """Refuse a dataset too large to read safely (more than
    :data:`automodal.io.readers.MAX_VALUES` numbers), before reading it."""
    problem = size_problem(int(ds.size), f"{label} (shape {ds.shape})")
    if problem:
        raise _Refused(problem)


def _check_length(ds: h5py.Dataset, label: str, n: int, side: str) -> None:
    """Refuse a channel dataset that is not 1-D with one entry per channel."""
    if ds.ndim != 1 or ds.shape[0] != n:
        raise _Refused(f"{label} has shape {ds.shape}, but /frf has {n} {side}")


def _check_shape(actual: tuple[int, ...], label: str, shape: tuple[int, ...], what: str) -> None:
    """Refuse an array of shape ``actual`` unless it is ``shape``."""
    if tuple(actual) != tuple(shape):
        raise _Refused(f"{label} has shape {tuple(actual)}, expected {tuple(shape)} ({what})")


def _check_finite(values: np.ndarray, label: str) -> None:
    """Refuse NaN or infinite values, saying how many there are."""
    bad = ~np.isfinite(values)
    if bad.any():
        raise _Refused(f"{label} has {int(bad.sum())} non-finite value(s) (NaN or inf)")


def _plain(value: Any) -> Any:
    """Turn an HDF5 attribute value into plain Python (str, int, float, bool, list, None)."""
    if isinstance(value, h5py.Empty):
        return None
    if isinstance(value, (np.ndarray, np.generic)):
        value = value.tolist()
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def _describe(exc: BaseException) -> str:
    """One line saying what an unexpected exception was."""
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


# --------------------------------------------------------------------------------- writing


def write_frf(path: str | os.PathLike[str], data: FRFData) -> None:
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

    Raises
    ------
    ValueError
        If ``data.quantity`` is not one of :data:`automodal.frfdata.QUANTITIES`.
    TypeError
        If an attribute value cannot be stored in HDF5.
    """
    if data.quantity not in QUANTITIES:
        raise ValueError(f"unknown quantity {data.quantity!r}")
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        _write_header(f, data)
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


def _write_header(f: h5py.File, data: FRFData) -> None:
    """Write the root attributes: format, version, quantity and the free attributes."""
    f.attrs["format"] = FORMAT_NAME
    f.attrs["version"] = FORMAT_VERSION
    f.attrs["quantity"] = data.quantity
    for key, value in data.attributes.items():
        if key not in _RESERVED_ATTRIBUTES:
            f.attrs[key] = _attribute_value(value)


def _attribute_value(value: Any) -> Any:
    """Make a plain Python value storable as an HDF5 attribute."""
    if value is None:
        return h5py.Empty("f8")
    if isinstance(value, (list, tuple)) and value and all(isinstance(v, str) for v in value):
        return np.array(value, dtype=h5py.string_dtype())
    return value


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
