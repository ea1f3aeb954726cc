"""Reading MATLAB files of samples: v4 to v7 with scipy.io, v7.3 (HDF5) with h5py.

The variables are read by name, without regard to case, as
:data:`automodal.io.sample_arrays.ROLES` lists them: the samples as ``samples``, ``data`` or
``signals`` (``--forces`` says which channels are forces) or as ``outputs`` and optionally
``inputs``; the rate as ``sample_rate``, ``fs``, ``samplerate`` or ``sampling_rate`` (Hz),
``dt`` (s) or a time vector ``time`` or ``t`` (s); channel names as a cell array of text
``channel_names`` or ``names`` (or ``output_names``, ``input_names``); ``quantity`` as text.
A matrix of samples may be (samples, channels) or (channels, samples): the longer axis is
the samples. Other variables (structs included) are ignored and listed in
``attributes["ignored_keys"]``.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from automodal.errors import InputError
from automodal.io.channels import Channels
from automodal.io.limits import check_size
from automodal.io.refusal import describe, read_refusing
from automodal.io.sample_arrays import ROLES, channels_from_named

__all__ = ["read_mat"]

_WANTED = {name for names in ROLES.values() for name in names}
_HDF5_INTERNAL = ("#refs#", "#subsystem#")


def read_mat(path: str | os.PathLike[str]) -> Channels:
    """Read the channels of samples in a MATLAB ``.mat`` file.

    Parameters
    ----------
    path : str or path-like
        A MATLAB file of version 4 to 7 (``scipy.io.loadmat``) or 7.3 (HDF5, ``h5py``).

    Returns
    -------
    Channels
        For :func:`automodal.io.channels.to_time_series`.

    Raises
    ------
    InputError
        One line naming the file: not a MATLAB file (or a damaged one), no recognised
        samples variable (the message lists the variables found and the names
        recognised), variables of the wrong type or shape, rates that disagree, or more
        than :data:`automodal.io.limits.MAX_VALUES` numbers (refused before loading).
    """
    return read_refusing(_read_mat, path)


def _read_mat(p: Path, source: str) -> Channels:
    import h5py

    if h5py.is_hdf5(p):
        arrays, ignored = _read_v73(p, source)
        kind = "MATLAB v7.3 file"
    else:
        arrays, ignored = _read_v5(p, source)
        kind = "MATLAB file"
    return channels_from_named(arrays, "variable", kind, others=ignored)


def _read_v5(p: Path, source: str) -> tuple[dict[str, Any], list[str]]:
    """The recognised variables of a v4-v7 file (and the names of the others)."""
    from scipy import io

    try:
        listing = io.whosmat(os.fspath(p))
    except Exception as exc:  # noqa: BLE001 - scipy raises many kinds on foreign files
        raise InputError(f"cannot read as a MATLAB file: {describe(exc)}", source) from exc
    wanted = [name for name, _, _ in listing if name.lower() in _WANTED]
    ignored = [name for name, _, _ in listing if name.lower() not in _WANTED]
    check_size(sum(math.prod(shape) for name, shape, _ in listing if name in wanted),
               "the variables", source)
    try:
        loaded = io.loadmat(os.fspath(p), variable_names=wanted, simplify_cells=True)
    except Exception as exc:  # noqa: BLE001
        raise InputError(f"cannot read as a MATLAB file: {describe(exc)}", source) from exc
    return {name: _text_or_array(loaded[name]) for name in wanted if name in loaded}, ignored


def _text_or_array(value: Any) -> Any:
    """A variable as text, a list of text, or an array of numbers."""
    if isinstance(value, str):
        return value.strip()
    if isinstance(value, (list, tuple)) or (isinstance(value, np.ndarray)
                                            and value.dtype.kind in "OUS"):
        items = list(np.asarray(value, dtype=object).reshape(-1))
        if all(isinstance(v, str) for v in items):
            return [v.strip() for v in items]
        return np.asarray(value, dtype=object)
    return np.asarray(value)


def _read_v73(p: Path, source: str) -> tuple[dict[str, Any], list[str]]:
    """The recognised variables of a v7.3 (HDF5) file (and the names of the others)."""
    import h5py

    arrays: dict[str, Any] = {}
    ignored: list[str] = []
    with h5py.File(p, "r") as f:
        for name in f:
            if name in _HDF5_INTERNAL:
                continue
            item = f[name]
            if name.lower() not in _WANTED or not isinstance(item, h5py.Dataset):
                ignored.append(name)
                continue
            arrays[name] = _v73_value(f, item, source)
    return arrays, ignored


def _v73_value(f: Any, ds: Any, source: str) -> Any:
    """One v7.3 variable: text for ``char``, a list for ``cell``, else an array (in the
    file's order, the transpose of MATLAB's: the readers orient samples by length)."""
    cls = ds.attrs.get("MATLAB_class", b"")
    cls = cls.decode() if isinstance(cls, bytes) else str(cls)
    if cls == "char":
        return "".join(chr(int(c)) for c in np.asarray(ds[()]).T.reshape(-1)).strip()
    if cls == "cell":
        return [_v73_value(f, f[ref], source) for ref in np.asarray(ds[()]).T.reshape(-1)]
    check_size(int(ds.size), f"variable {ds.name!r}", source)
    return np.asarray(ds[()])
