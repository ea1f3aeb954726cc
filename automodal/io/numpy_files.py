"""Reading NumPy files of samples: ``.npy`` arrays, and ``.npz`` archives of either kind.

A ``.npy`` file is one array of samples (:func:`read_npy`): 1-D (one channel) or 2-D in
either orientation, the longer axis being the samples; a channel that increases throughout
is a time axis (:mod:`automodal.io.sample_arrays`). An ``.npz`` archive (:func:`read_npz_any`)
holds FRFs (keys ``frequency`` and ``frf``: :func:`automodal.io.tabular.read_npz`) or
samples (keys ``samples``, ``data`` or ``signals``, or ``outputs`` and ``inputs``, with
``sample_rate``, ``fs``, ``dt`` or ``time``; :data:`automodal.io.sample_arrays.ROLES`); an
archive with keys of both kinds, or of neither, is refused.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from automodal.errors import InputError
from automodal.frfdata import FRFData
from automodal.io.channels import Channels
from automodal.io.limits import check_size
from automodal.io.refusal import describe, read_refusing
from automodal.io.sample_arrays import (
    LAYOUT,
    ROLES,
    channels_from_array,
    channels_from_named,
    is_samples_key,
)
from automodal.io.tabular import NPZ_KEYS, NPZ_LAYOUT, npy_shape, npz_frfdata, npz_members

__all__ = ["read_npy", "read_npz_any"]

_FRF_KEYS = ("frequency", "frf")


def read_npy(path: str | os.PathLike[str]) -> Channels:
    """Read the channels of a ``.npy`` array of samples.

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    Channels
        Named ``ch0, ch1, ...`` by their position in the array; the sample rate when a
        channel is a time axis (else ``--sample-rate`` must give it).

    Raises
    ------
    InputError
        One line naming the file: not a ``.npy`` array (or a damaged one), pickled objects,
        more than :data:`automodal.io.limits.MAX_VALUES` numbers (refused from the header),
        and what :func:`automodal.io.sample_arrays.channels_from_array` refuses.
    """
    return read_refusing(_read_npy, path)


def _read_npy(p: Path, source: str) -> Channels:
    with open(p, "rb") as fp:
        shape = npy_shape(fp)
    if shape is None:
        raise InputError("not a .npy array file", source)
    check_size(int(np.prod(shape)), f"the array (shape {shape})", source)
    try:
        values = np.load(p, allow_pickle=False)
    except Exception as exc:  # noqa: BLE001 - numpy raises many kinds on a damaged file
        raise InputError(f"cannot read as a .npy array: {describe(exc)}", source) from exc
    return channels_from_array(values, "the array", "NumPy array")


def read_npz_any(path: str | os.PathLike[str]) -> FRFData | Channels:
    """Read an ``.npz`` archive of FRFs or of samples, as its keys say.

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    FRFData or Channels
        The FRFs (:func:`automodal.io.tabular.read_npz`), or the channels of samples.

    Raises
    ------
    InputError
        One line naming the file: keys of FRFs and of samples in one archive, keys of
        neither, and what the reader of either kind refuses.
    """
    return read_refusing(_read_npz_any, path)


def _read_npz_any(p: Path, source: str) -> FRFData | Channels:
    try:
        loaded = np.load(p, allow_pickle=False)
        if not isinstance(loaded, np.lib.npyio.NpzFile):
            raise InputError("a single .npy array, not an .npz archive (name it .npy)", source)
        with loaded as archive:
            keys = list(archive.files)
            samples = [k for k in keys if is_samples_key(k)]
            frf = [k for k in keys if k in _FRF_KEYS]
            if samples and frf:
                raise InputError(f"keys of FRFs ({', '.join(frf)}) and of samples "
                                 f"({', '.join(samples)}) in one archive: keep one kind", source)
            if not samples and not frf:
                found = ", ".join(sorted(keys)) or "none"
                raise InputError(f"neither FRFs nor samples (keys found: {found}); FRFs need "
                                 f"keys 'frequency' and 'frf'; samples: {LAYOUT}", source)
            if frf:
                arrays = npz_members(archive, NPZ_KEYS, NPZ_LAYOUT, source)
            else:
                wanted = [k for k in keys if any(k.lower() in names for names in ROLES.values())]
                arrays = npz_members(archive, wanted, LAYOUT, source)
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - zipfile, zlib and numpy raise many kinds
        raise InputError(f"cannot read as an .npz archive: {describe(exc)}", source) from exc
    if frf:
        return npz_frfdata(arrays, keys, source)
    return channels_from_named({k: _plain(v) for k, v in arrays.items()}, "key",
                               "NPZ archive of samples",
                               others=[k for k in keys if k not in arrays])


def _plain(value: np.ndarray) -> Any:
    """A member as an array of numbers, or as text (a string, or a list of strings)."""
    if value.dtype.kind in "US":
        items = [v.decode("utf-8", "replace") if isinstance(v, bytes) else str(v)
                 for v in value.reshape(-1).tolist()]
        return items[0] if value.ndim == 0 else items
    return value
