"""Validation on real measured tests in ../shared/realdata (skipped when it is absent)."""

from __future__ import annotations

import gzip
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from automodal.frfdata import FRFData
from automodal.pipeline import Settings, identify

ROOT = Path(__file__).resolve().parents[1]
REALDATA = ROOT.parent / "shared" / "realdata"

pytestmark = [
    pytest.mark.realdata,
    pytest.mark.skipif(not REALDATA.is_dir(), reason="../shared/realdata is absent"),
]

MODELAB_REFERENCE_HZ = np.array([111.99, 306.86, 596.37, 974.14])


def read_signalcalc(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """One DataPhysics SignalCalc ASCII FRF export (gzip): frequency and complex FRF."""
    with gzip.open(path, "rt", encoding="latin-1") as fh:
        rows = [line.split() for line in fh]
    table = np.array([[float(x) for x in r] for r in rows if len(r) == 3 and r[0][0].isdigit()])
    return table[:, 0], table[:, 1] + 1j * table[:, 2]


@pytest.fixture(scope="module")
def modelab() -> FRFData:
    folder = REALDATA / "modelab_beam"
    frfs = [read_signalcalc(folder / f"Hxysv{i:05d}.txt.gz") for i in range(1, 10)]
    H = np.stack([h for _, h in frfs], axis=1)[:, None, :]  # 1 accelerometer x 9 hammer points
    return FRFData(frequency=frfs[0][0], frf=H, quantity="acceleration",
                   input_names=[f"hit{i}" for i in range(1, 10)], source="modelab_beam")


def test_modelab_roving_hammer_beam(modelab):
    """All 4 reference modes called physical, within 0.5 %, in the setup's 65-1000 Hz band."""
    result = identify(modelab, Settings(band_hz=(65.0, 1000.0), seed=0))
    found = np.array([m.frequency_hz for m in result.physical_modes])
    for f_ref in MODELAB_REFERENCE_HZ:
        assert np.min(np.abs(found - f_ref) / f_ref) < 0.005, (f_ref, found)
    assert found.size <= 6, found
    assert result.reciprocity


def test_ladisk_uff_runs_end_to_end(tmp_path):
    uff = REALDATA / "ladisk_beam_frf" / "measurement.uff"
    out = tmp_path / "r.json"
    proc = subprocess.run(
        [sys.executable, "-m", "automodal", "identify", str(uff), "--bootstrap", "30",
         "-o", str(out), "--quiet"],
        capture_output=True, text=True,
    )
    assert proc.returncode == 0, proc.stderr
    report = json.loads(out.read_text())
    assert report["input"]["n_inputs"] == 3
    assert report["summary"]["n_physical"] >= 3
