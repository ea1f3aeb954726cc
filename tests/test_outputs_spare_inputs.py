"""An output that is one of the command's inputs is refused before any work (exit 2, one
line): writing it would replace the input (``identify in.h5 -o in.h5`` once turned the FRF
file into a report)."""

from __future__ import annotations

import hashlib
import os
import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from automodal.cli import main

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data" / "chain6.h5"


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _refused(args: list[str], spared: Path) -> None:
    before = _digest(spared)
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert "is also an input" in lines[0] and "choose another output" in lines[0]
    assert _digest(spared) == before


@pytest.fixture
def frf(tmp_path: Path) -> Path:
    path = tmp_path / "data" / "in.h5"
    path.parent.mkdir()
    shutil.copy(SAMPLE, path)
    return path


def test_identify_refuses_its_input_as_report(frf: Path):
    _refused(["identify", str(frf), "-o", str(frf)], frf)


def test_identify_refuses_the_input_named_another_way(frf: Path, tmp_path: Path):
    other = tmp_path / "elsewhere"
    other.mkdir()
    roundabout = other / ".." / "data" / "in.h5"
    _refused(["identify", str(frf), "-o", str(roundabout)], frf)
    link = tmp_path / "link.h5"
    os.symlink(frf, link)
    _refused(["identify", str(frf), "-o", str(link)], frf)


def test_identify_refuses_its_baseline_as_report(frf: Path, tmp_path: Path):
    baseline = tmp_path / "base.json"
    baseline.write_text("{}")
    _refused(["identify", str(frf), "--baseline", str(baseline), "-o", str(baseline)],
             baseline)


def test_convert_refuses_its_input_as_output(frf: Path):
    _refused(["convert", str(frf), str(frf)], frf)


def test_track_refuses_a_report_as_history(tmp_path: Path):
    report = tmp_path / "r2.h5"
    report.write_bytes(b"not read: refused before")
    _refused(["track", str(report), "-o", str(report)], report)


def test_design_refuses_its_modes_file_as_lines_file(tmp_path: Path):
    modes = tmp_path / "modes.csv"
    modes.write_text("frequency_hz,damping_ratio\n10,0.01\n")
    _refused(["design", "--band", "5", "20", "--lines", "50", "--modes", str(modes),
              "-o", str(modes)], modes)


def test_a_distinct_output_is_written(frf: Path, tmp_path: Path):
    out = tmp_path / "data" / "in.json"  # same stem, another file
    result = CliRunner().invoke(main, ["identify", str(frf), "-o", str(out), "--quiet",
                                       "--bootstrap", "20"])
    assert result.exit_code == 0, result.output
    assert out.exists()
