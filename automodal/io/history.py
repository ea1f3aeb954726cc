"""The history file: modes tracked over time (``automodal track``), as HDF5.

Layout (version 1): root attributes ``format = "automodal-history"``, ``version = 1``,
``automodal_version``, ``created``, ``baseline`` (where the baseline report came from) and
``thresholds`` (JSON text). For ``T`` reports sorted by time and ``M`` tracked modes:

=========================================  ==========  ======================================
dataset                                    shape       meaning
=========================================  ==========  ======================================
``/time``, ``/time_source``, ``/report``   (T,)        ISO 8601 UTC time; ``test_date`` or
                                                       ``created``; the report's path
``/flagged``, ``/n_new``                   (T,)        any mode flagged; new physical modes
``/modes/id``                              (M,)        the baseline's mode ids
``/modes/number``                          (M,)        their mode numbers (1, 2, ...;
                                                       absent in older files: 1..M)
``/modes/baseline_frequency_hz``,          (M,)        the baseline's values
``/modes/baseline_damping_ratio``
``/frequency_hz``, ``/frequency_std_hz``,  (T, M)      per report and mode; NaN when missing
``/damping_ratio``, ``/damping_std``,
``/mac``
``/frequency_ci95_hz``, ``/damping_ci95``  (T, M, 2)   bootstrap 95 % intervals
``/mode_flagged``, ``/missing``            (T, M)      bool
=========================================  ==========  ======================================
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import h5py
import numpy as np

from automodal import __version__
from automodal.errors import InputError
from automodal.io.atomic import hdf5_in_memory
from automodal.report_model import utc_now
from automodal.tracking import History, Thresholds

__all__ = ["FORMAT_NAME", "FORMAT_VERSION", "is_history_file", "read_history", "write_history"]

FORMAT_NAME = "automodal-history"
"""Value of the root attribute ``format``."""

FORMAT_VERSION = 1
"""The version this module writes, and the newest it reads."""

_STRINGS = {"time": "times", "time_source": "time_sources", "report": "labels"}
_ROWS = ("flagged", "n_new")
_MODES = {"id": "mode_ids", "baseline_frequency_hz": "baseline_frequency_hz",
          "baseline_damping_ratio": "baseline_damping_ratio"}
_TABLES = ("frequency_hz", "frequency_std_hz", "frequency_ci95_hz", "damping_ratio",
           "damping_std", "damping_ci95", "mac", "mode_flagged", "missing")


def write_history(path: str | os.PathLike[str], history: History) -> Path:
    """Write a :class:`History` to an HDF5 file, atomically.

    Parameters
    ----------
    path : str or path-like
        The file (any suffix; ``.h5`` is usual).
    history : History

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    target = Path(path)
    text = h5py.string_dtype()
    with hdf5_in_memory(target) as f:
        f.attrs["format"] = FORMAT_NAME
        f.attrs["version"] = FORMAT_VERSION
        f.attrs["automodal_version"] = __version__
        f.attrs["created"] = utc_now()
        f.attrs["baseline"] = history.baseline_label
        f.attrs["thresholds"] = json.dumps(history.thresholds.to_dict())
        for name, attr in _STRINGS.items():
            f.create_dataset(name, data=np.array(getattr(history, attr), dtype=object), dtype=text)
        f.create_dataset("flagged", data=np.asarray(history.flagged, dtype=bool))
        f.create_dataset("n_new", data=np.asarray(history.n_new, dtype=np.int64))
        for name, attr in _MODES.items():
            f.create_dataset(f"modes/{name}", data=np.asarray(getattr(history, attr)))
        f.create_dataset("modes/number", data=np.asarray(history.mode_numbers, dtype=np.int64))
        for name in _TABLES:
            f.create_dataset(name, data=np.asarray(getattr(history, name)))
    return target


def is_history_file(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is an HDF5 file with ``format = "automodal-history"``."""
    try:
        if not h5py.is_hdf5(path):
            return False
        with h5py.File(path, "r") as f:
            return _text(f.attrs.get("format")) == FORMAT_NAME
    except (OSError, ValueError):
        return False


def read_history(path: str | os.PathLike[str]) -> History:
    """Read a history file written by :func:`write_history`.

    Raises
    ------
    InputError
        If the file is missing, not HDF5, not a history file, of a newer version, or
        lacks a dataset. The message names the file.
    """
    source = os.fspath(path)
    if not Path(path).is_file():
        raise InputError("no such history file", source)
    if not is_history_file(path):
        raise InputError(f"not an automodal history file (format is not {FORMAT_NAME!r})", source)
    try:
        with h5py.File(path, "r") as f:
            version = int(f.attrs.get("version", 0))
            if version > FORMAT_VERSION:
                raise InputError(f"history version {version} is newer than this automodal "
                                 f"reads ({FORMAT_VERSION})", source)
            values = {attr: [_text(x) for x in f[name][()]] for name, attr in _STRINGS.items()}
            values.update({name: f[name][()] for name in _ROWS})
            values.update({attr: f[f"modes/{name}"][()] for name, attr in _MODES.items()})
            if "modes/number" in f:
                values["mode_numbers"] = f["modes/number"][()]
            values.update({name: f[name][()] for name in _TABLES})
            values["baseline_label"] = _text(f.attrs.get("baseline", ""))
            values["thresholds"] = Thresholds.from_dict(json.loads(_text(f.attrs["thresholds"])))
    except (KeyError, ValueError, OSError) as exc:
        msg = " ".join(str(exc).split()) or type(exc).__name__
        raise InputError(f"cannot read the history: {msg}", source) from None
    return History(**values)


def _text(value: object) -> str:
    """An HDF5 string attribute or element as ``str``."""
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    return "" if value is None else str(value)
