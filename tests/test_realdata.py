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
from automodal.pipeline import identify
from automodal.settings import Settings

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
    """All 4 reference modes called physical, within 0.5 %, in the setup's 65-1000 Hz band,
    and no physical mode elsewhere.

    A resonance whose peak moves between the nine hits (974 Hz: four lines, 974.08 to
    974.16 Hz; 596 Hz: three) is fitted by one model of common poles with several, and may
    be reported as several modes: at most as many as the lines its peak takes."""
    result = identify(modelab, Settings(band_hz=(65.0, 1000.0), seed=0))
    found = np.array([m.frequency_hz for m in result.physical_modes])
    f = modelab.frequency
    for f_ref in MODELAB_REFERENCE_HZ:
        assert np.min(np.abs(found - f_ref) / f_ref) < 0.005, (f_ref, found)
        near = np.abs(f / f_ref - 1.0) < 0.005
        peaks = {int(np.argmax(np.abs(h[near]))) for h in modelab.frf[:, 0, :].T}
        assert np.count_nonzero(np.abs(found / f_ref - 1.0) < 0.005) <= len(peaks), found
    off = np.abs(found[:, None] / MODELAB_REFERENCE_HZ[None, :] - 1.0).min(axis=1)
    assert np.all(off < 0.005), found  # no noise mode anywhere in the band
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
    # issue 15, item 6: 1 Hz lines do not resolve damping of 0.01-0.1 %: every mode whose
    # half-power bandwidth is below 1.47 lines says so, and no resonance comes out twice
    # (the 959 Hz mode did)
    physical = sorted(m["frequency_hz"] for m in report["modes"] if m["physical"])
    assert np.all(np.diff(physical) > 5.0), physical
    assert sum(abs(f - 959.0) < 5.0 for f in physical) == 1, physical
    for m in report["modes"]:
        if m["physical"] and 2 * m["damping_ratio"] * m["frequency_hz"] < 1.47:
            assert any(f"{m['frequency_hz']:.4g} Hz" in w and "1.47 line spacings" in w
                       for w in report["warnings"])


WEIMAR_REFERENCE_HZ = np.array([1.2283, 1.4358, 2.1000, 4.0175, 4.7704, 6.6824, 7.6157, 9.6653,
                                12.1663, 12.5979, 13.8545])


def test_weimar_steel_frame_output_only(tmp_path):
    """Ambient setup 1, fully automatic: at least 9 of 11 reference modes physical within 1 %,
    at most 3 extra physical modes below 15 Hz."""
    from automodal.core.from_time import as_frfdata
    from automodal.io.readers import read_any
    from automodal.io.time_file import write_time
    from automodal.timedata import TimeSeries

    raw = np.load(REALDATA / "weimar_steel_frame" / "measurement_1" / "measurement_1.npy")
    ts = TimeSeries(outputs=raw[:, :5], inputs=None, sample_rate=256.0,
                    output_names=["vib_l", "vib_r", "vib_t", "ref_x", "ref_y"],
                    attributes={"quantity": "velocity"})
    path = tmp_path / "weimar1.h5"
    write_time(path, ts)
    data = as_frfdata(read_any(path))  # the time route: half spectra, automatic references
    assert data.attributes["analysis"] == "operational"
    result = identify(data, Settings(seed=0))
    found = np.array([m.frequency_hz for m in result.physical_modes])
    hits = [np.min(np.abs(found - f) / f) < 0.01 for f in WEIMAR_REFERENCE_HZ]
    assert sum(hits) >= 9, (found, hits)
    extra = [f for f in found
             if f < 15 and np.min(np.abs(WEIMAR_REFERENCE_HZ - f) / WEIMAR_REFERENCE_HZ) >= 0.01]
    assert len(extra) <= 3, extra


def test_weimar_steel_frame_from_the_command_line(tmp_path):
    """The command ``docs/validation.md`` gives for setup 1 (five channels as ``.npy``, no
    forces): it ran into the repeated records' scale rule, whose median the stretches'
    skewed half spectra put at 0.43 of their mean, and exited 2. All 11 reference modes
    physical within 1 %, at most 3 other physical modes below 15 Hz."""
    raw = np.load(REALDATA / "weimar_steel_frame" / "measurement_1" / "measurement_1.npy")
    path = tmp_path / "weimar1.npy"
    np.save(path, raw[:, :5])
    out = tmp_path / "r.json"
    proc = subprocess.run(
        [sys.executable, "-m", "automodal", "identify", str(path), "--sample-rate", "256",
         "--forces", "none", "--quantity", "velocity", "-o", str(out), "--quiet"],
        capture_output=True, text=True,
    )
    assert proc.returncode == 0, proc.stderr
    found = np.array([m["frequency_hz"] for m in json.loads(out.read_text())["modes"]
                      if m["physical"]])
    hits = [np.min(np.abs(found - f) / f) < 0.01 for f in WEIMAR_REFERENCE_HZ]
    assert all(hits), (found, hits)
    extra = [f for f in found
             if f < 15 and np.min(np.abs(WEIMAR_REFERENCE_HZ - f) / WEIMAR_REFERENCE_HZ) >= 0.01]
    assert len(extra) <= 3, extra


LADISK_PEAKS_HZ = np.array(
    [810.0, 900.0, 1518.0, 2640.0, 3008.0, 3669.0, 4128.0, 4164.0, 4392.0])
"""The peaks the LADISK hammer data's README names (of its weaker 3008-3162 Hz ones, the
strongest, 3008). The 1518 Hz mode is narrower than a line spacing: its SNR^2 needs every
line near its peak (``whitening.quadrature_lines``); hit 5 alone still calls it noise
(benchmarks/results_impact.md)."""


def _ladisk_hits(which: list[int]):
    from automodal.timedata import TimeSeries

    folder = REALDATA / "ladisk_impact_timeseries"
    hits = [np.load(folder / f"measurements_{k}.npy") for k in which]
    return TimeSeries(outputs=np.concatenate([h[2] for h in hits])[:, None],
                      inputs=np.concatenate([h[1] for h in hits])[:, None],
                      sample_rate=25600.0, attributes={"quantity": "acceleration"},
                      source="ladisk_impact_timeseries")


@pytest.mark.slow
@pytest.mark.parametrize("which", [[1, 2, 3, 4, 5], [1]], ids=["five_hits", "one_hit"])
def test_ladisk_hammer_hits(which):
    """The README's peaks physical; the band cut where the hammer stops exciting (-20 dB);
    no physical mode seen by a small share of the replicates; split into sub-bands."""
    result = identify(_ladisk_hits(which), Settings(seed=0))
    assert result.band_hz[1] < 7500.0  # the force spectrum's -20 dB point, 7.0-7.2 kHz
    found = np.array([m.frequency_hz for m in result.physical_modes])
    for f in LADISK_PEAKS_HZ:
        assert np.min(np.abs(found - f)) < 2.0, (f, found)
    assert min(m.n_members for m in result.physical_modes) >= 50
    assert "sub_bands" in result.orders
