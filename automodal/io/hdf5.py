"""HDF5 helpers shared by the readers and writers of automodal's HDF5 files.

Opening a file read-only with a refusal that says what is wrong (empty, not HDF5, damaged),
getting a group or a dataset that must be one, writing the ``/time`` group (both writers of
automodal's files do), typed dataset readers that refuse the wrong
dtype, an empty dataset or one too large to read safely (:data:`~automodal.io.limits.
MAX_VALUES`, checked before reading), string lists, and the conversion of attribute values
to plain Python and back. Every problem is raised as :class:`~automodal.io.refusal.Refused`
(the reader's :func:`~automodal.io.refusal.read_refusing` adds the file's name).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import h5py
import numpy as np

from automodal.io.limits import size_problem
from automodal.io.refusal import READ_ERRORS, Refused, describe

if TYPE_CHECKING:
    from automodal.timedata import TimeSeries

__all__ = [
    "attribute_value",
    "check_dataset_size",
    "check_shape",
    "complex_array",
    "dataset",
    "group",
    "has_hdf5_signature",
    "int_array",
    "open_hdf5",
    "plain",
    "real_array",
    "string_list",
    "write_time_group",
]


def open_hdf5(path: Path) -> h5py.File:
    """Open ``path`` read-only as HDF5, refusing files that are not HDF5 or are damaged.

    Parameters
    ----------
    path : Path
        An existing file.

    Returns
    -------
    h5py.File
        Open read-only; the caller closes it.

    Raises
    ------
    Refused
        For an empty file, a file without the HDF5 signature, or a damaged one.
    """
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        if path.stat().st_size == 0:
            raise Refused("the file is empty (0 bytes), not an HDF5 file") from exc
        if not has_hdf5_signature(path, unreadable=True):
            raise Refused("not an HDF5 file") from exc
        raise Refused(f"damaged or truncated HDF5 file: {describe(exc)}") from exc


def has_hdf5_signature(path: Path, unreadable: bool = False) -> bool:
    """Whether ``path`` is an HDF5 file, by its signature.

    Parameters
    ----------
    path : Path
    unreadable : bool
        The answer when the signature cannot be read (False: not known to be HDF5; True,
        for a refusal that should not call a damaged file "not HDF5").

    Returns
    -------
    bool
    """
    try:
        return bool(h5py.is_hdf5(path))
    except READ_ERRORS:
        return unreadable


def group(parent: h5py.Group, name: str) -> h5py.Group | None:
    """The group ``name`` under ``parent``, None when absent; refuse a dataset there."""
    obj = parent.get(name)
    if obj is not None and not isinstance(obj, h5py.Group):
        raise Refused(f"{_h5name(parent, name)} must be a group, not a dataset")
    return obj


def dataset(parent: h5py.Group, name: str) -> h5py.Dataset | None:
    """The dataset ``name`` under ``parent``, None when absent; refuse a group there."""
    obj = parent.get(name)
    if obj is not None and not isinstance(obj, h5py.Dataset):
        raise Refused(f"{_h5name(parent, name)} must be a dataset, not a group")
    return obj


def _h5name(parent: h5py.Group, name: str) -> str:
    """The absolute HDF5 name of ``name`` under ``parent``."""
    return f"{parent.name.rstrip('/')}/{name}"


def complex_array(ds: h5py.Dataset, label: str, ndim: int, axes: str) -> np.ndarray:
    """Read a complex dataset of ``ndim`` axes as complex128.

    Parameters
    ----------
    ds : h5py.Dataset
    label : str
        Its name in messages (``"/frf"``).
    ndim : int
        The number of axes it must have.
    axes : str
        What the axes are, for messages (``"(n_freq, n_outputs, n_inputs)"``).

    Raises
    ------
    Refused
        If it has another number of axes, is real, empty, or too large to read.
    """
    if ds.ndim != ndim:
        raise Refused(f"{label} must be {ndim}-D {axes}, but has shape {ds.shape}")
    if ds.dtype.kind != "c":
        raise Refused(
            f"{label} is not complex (dtype {ds.dtype}); real FRFs are refused, "
            "not given zero phase"
        )
    if ds.size == 0:
        raise Refused(f"{label} is empty (shape {ds.shape})")
    check_dataset_size(ds, label)
    return np.asarray(ds[()], dtype=np.complex128)


def real_array(ds: h5py.Dataset, label: str) -> np.ndarray:
    """Read a dataset of real numbers as float64, refusing other dtypes, empty data and a
    dataset too large to read."""
    if ds.dtype.kind not in "fiu":
        raise Refused(f"{label} must hold real numbers, not dtype {ds.dtype}")
    if ds.size == 0:
        raise Refused(f"{label} is empty (shape {ds.shape})")
    check_dataset_size(ds, label)
    return np.asarray(ds[()], dtype=np.float64)


def int_array(ds: h5py.Dataset, label: str) -> np.ndarray:
    """Read a dataset of integers as int64, refusing other dtypes and a dataset too large
    to read."""
    if ds.dtype.kind not in "iu":
        raise Refused(f"{label} must hold integers, not dtype {ds.dtype}")
    check_dataset_size(ds, label)
    return np.asarray(ds[()], dtype=np.int64)


def string_list(ds: h5py.Dataset, label: str) -> list[str]:
    """Read a dataset of UTF-8 strings as a list of str (undecodable bytes replaced),
    refusing other dtypes and a dataset too large to read."""
    if h5py.check_string_dtype(ds.dtype) is None:
        raise Refused(f"{label} must hold strings, not dtype {ds.dtype}")
    check_dataset_size(ds, label)
    return [str(s) for s in ds.asstr(errors="replace")[()]]


def check_dataset_size(ds: h5py.Dataset, label: str) -> None:
    """Refuse a dataset too large to read safely (more than
    :data:`automodal.io.limits.MAX_VALUES` numbers), before reading it."""
    problem = size_problem(int(ds.size), f"{label} (shape {ds.shape})")
    if problem:
        raise Refused(problem)


def check_shape(actual: tuple[int, ...], label: str, shape: tuple[int, ...], what: str) -> None:
    """Refuse an array of shape ``actual`` unless it is ``shape`` (``what`` says why)."""
    if tuple(actual) != tuple(shape):
        raise Refused(f"{label} has shape {tuple(actual)}, expected {tuple(shape)} ({what})")


def plain(value: Any) -> Any:
    """Turn an HDF5 attribute value into plain Python (str, int, float, bool, list, None).

    Parameters
    ----------
    value : Any
        As h5py gives it (numpy scalars and arrays, bytes, :class:`h5py.Empty`).

    Returns
    -------
    Any
    """
    if isinstance(value, h5py.Empty):
        return None
    if isinstance(value, (np.ndarray, np.generic)):
        value = value.tolist()
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    return value


def attribute_value(value: Any) -> Any:
    """Make a plain Python value storable as an HDF5 attribute (the inverse of
    :func:`plain`: None as an empty attribute, a list of str as a string array).

    Parameters
    ----------
    value : Any

    Returns
    -------
    Any
    """
    if value is None:
        return h5py.Empty("f8")
    if isinstance(value, (list, tuple)) and value and all(isinstance(v, str) for v in value):
        return np.array(value, dtype=h5py.string_dtype())
    return value


def write_time_group(f: h5py.File, ts: TimeSeries) -> None:
    """Write the ``/time`` group of ``ts`` (samples and ``sample_rate``) into an open file;
    the channel names (``/outputs/name``, ``/inputs/name``) are the caller's.

    Parameters
    ----------
    f : h5py.File
        Open for writing, without a ``/time`` group.
    ts : TimeSeries
        The records (:class:`~automodal.timedata.TimeSeries`).
    """
    time = f.create_group("time")
    time.attrs["sample_rate"] = float(ts.sample_rate)
    time.create_dataset("outputs", data=np.asarray(ts.outputs, dtype=np.float64))
    if ts.inputs is not None:
        time.create_dataset("inputs", data=np.asarray(ts.inputs, dtype=np.float64))
