"""automodal: automated modal parameter estimation from vibration test data.

The public API::

    import automodal

    data = automodal.read("test.h5")                  # FRFData or TimeSeries
    result = automodal.identify(data, automodal.Settings(seed=1))
    for mode in result.physical_modes:
        print(mode.frequency_hz, mode.damping_ratio, mode.physicalness)

Names are imported on first use (PEP 562), so that ``import automodal`` and the command
line's ``--help`` stay fast.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

_EXPORTS = {
    "identify": ("automodal.pipeline", "identify"),
    "Settings": ("automodal.settings", "Settings"),
    "Result": ("automodal.result", "Result"),
    "IdentifiedMode": ("automodal.result", "IdentifiedMode"),
    "FRFData": ("automodal.frfdata", "FRFData"),
    "TimeSeries": ("automodal.timedata", "TimeSeries"),
    "read": ("automodal.io.readers", "read_any"),
    "InputError": ("automodal.errors", "InputError"),
}

__all__ = [
    "FRFData",
    "IdentifiedMode",
    "InputError",
    "Result",
    "Settings",
    "TimeSeries",
    "__version__",
    "identify",
    "read",
]

if TYPE_CHECKING:
    from automodal.errors import InputError
    from automodal.frfdata import FRFData
    from automodal.io.readers import read_any as read
    from automodal.pipeline import identify
    from automodal.result import IdentifiedMode, Result
    from automodal.settings import Settings
    from automodal.timedata import TimeSeries


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        module, attr = _EXPORTS[name]
        value = getattr(importlib.import_module(module), attr)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'automodal' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
