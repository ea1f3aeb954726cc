"""The public API: the names ``automodal`` exports, and that they work together."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import automodal

ROOT = Path(__file__).resolve().parents[1]


def test_every_exported_name_resolves():
    for name in automodal.__all__:
        assert getattr(automodal, name) is not None, name
    assert set(automodal.__all__) <= set(dir(automodal))
    assert set(automodal.__all__) == {"__version__", *automodal._EXPORTS}


def test_exports_are_the_modules_objects():
    from automodal.frfdata import FRFData
    from automodal.io.readers import read_any
    from automodal.pipeline import identify
    from automodal.result import Result
    from automodal.settings import Settings
    from automodal.timedata import TimeSeries

    assert automodal.identify is identify
    assert automodal.Settings is Settings
    assert automodal.Result is Result
    assert automodal.read is read_any
    assert automodal.FRFData is FRFData
    assert automodal.TimeSeries is TimeSeries


def test_unknown_name_is_an_attribute_error():
    try:
        automodal.no_such_thing  # noqa: B018
    except AttributeError as exc:
        assert "no_such_thing" in str(exc)
    else:
        raise AssertionError("no AttributeError")


def test_read_identify_on_the_sample():
    data = automodal.read(ROOT / "sample_data" / "chain6.h5")
    result = automodal.identify(data, automodal.Settings(seed=1, n_bootstrap=20))
    assert isinstance(result, automodal.Result)
    assert len(result.physical_modes) == 6


def test_import_loads_no_heavy_module():
    code = ("import sys, automodal; heavy = [m for m in ('numpy', 'scipy', 'h5py', 'matplotlib')"
            " if m in sys.modules]; print(heavy)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]"
