"""The root header of automodal's HDF5 test file (``docs/frf-file.md``), shared by the FRF
and the time-series readers and writers: the ``format``, ``version`` and ``quantity``
attributes, and the free attributes (structure, date, ...) that are copied into reports.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import h5py

from automodal.frfdata import quantity_problem
from automodal.io.hdf5 import attribute_value, plain
from automodal.io.refusal import Refused

__all__ = [
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "RESERVED_ATTRIBUTES",
    "free_attributes",
    "read_header",
    "write_header",
]

FORMAT_NAME = "automodal-frf"
"""Value of the root attribute ``format``."""

FORMAT_VERSION = 1
"""The newest file version this package reads, and the one it writes."""

RESERVED_ATTRIBUTES = ("format", "version", "quantity")
"""Root attributes of the header itself, not copied to or from the free attributes."""


def read_header(attrs: h5py.AttributeManager) -> str:
    """Check the ``format`` and ``version`` attributes and return the ``quantity``.

    Parameters
    ----------
    attrs : h5py.AttributeManager
        The root attributes.

    Returns
    -------
    str
        The quantity (``"displacement"`` when the file does not say).

    Raises
    ------
    Refused
        For another format, a version that is not an integer or is newer than
        :data:`FORMAT_VERSION`, or an unknown quantity.
    """
    if "format" in attrs:
        fmt = plain(attrs["format"])
        if fmt != FORMAT_NAME:
            raise Refused(f"format attribute is {fmt!r}, not {FORMAT_NAME!r}")
    if "version" in attrs:
        _check_version(plain(attrs["version"]))
    quantity = plain(attrs["quantity"]) if "quantity" in attrs else "displacement"
    problem = quantity_problem(quantity)
    if problem:
        raise Refused(problem)
    return quantity


def _check_version(version: Any) -> None:
    """Refuse a version that is not an integer this reader knows."""
    if isinstance(version, float) and version.is_integer():
        version = int(version)  # tools such as MATLAB write numeric attributes as doubles
    if isinstance(version, bool) or not isinstance(version, int):
        raise Refused(f"version attribute must be an integer, not {version!r}")
    if version > FORMAT_VERSION:
        raise Refused(
            f"file version {version} is newer than this reader knows ({FORMAT_VERSION}); "
            "update automodal"
        )
    if version < 1:
        raise Refused(f"unknown file version {version}")


def free_attributes(attrs: h5py.AttributeManager) -> dict[str, Any]:
    """The root attributes other than :data:`RESERVED_ATTRIBUTES`, as plain Python values.

    Parameters
    ----------
    attrs : h5py.AttributeManager

    Returns
    -------
    dict
    """
    return {key: plain(attrs[key]) for key in attrs if key not in RESERVED_ATTRIBUTES}


def write_header(f: h5py.File, attributes: Mapping[str, Any], quantity: str | None) -> None:
    """Write the root attributes: format, version, quantity (when given) and the free
    attributes (keys of :data:`RESERVED_ATTRIBUTES` skipped).

    Parameters
    ----------
    f : h5py.File
        Open for writing.
    attributes : mapping
        Free attributes, plain Python values.
    quantity : str or None
        The response quantity; None writes none.

    Raises
    ------
    TypeError
        If an attribute value cannot be stored in HDF5.
    """
    f.attrs["format"] = FORMAT_NAME
    f.attrs["version"] = FORMAT_VERSION
    if quantity is not None:
        f.attrs["quantity"] = quantity
    for key, value in attributes.items():
        if key not in RESERVED_ATTRIBUTES:
            f.attrs[key] = attribute_value(value)
