"""Issue 15, item 7: text exports of acquisition software (SignalCalc style: title, channel and
unit lines before the columns, Latin-1, gzipped, one file per FRF) read in one step, and a
batch folder that leaves out a readme.txt instead of failing every run on it."""

from __future__ import annotations

import gzip
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from automodal.app.batch import expand_inputs
from automodal.errors import InputError
from automodal.io.frf_file import read_frf
from automodal.io.readers import read_any, reader_suffix
from automodal.io.stacking import stack_frfs
from automodal.io.tabular import holds_number_rows, read_csv

REALDATA = Path(__file__).parents[1].parent / "shared" / "realdata"
FREQ = np.arange(0.0, 40.0, 0.5)


def frf(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.standard_normal(FREQ.size) + 1j * rng.standard_normal(FREQ.size)


def signalcalc_text(h: np.ndarray, unit: str = "(m/s\u00b2)(N)") -> str:
    """A SignalCalc-style ASCII FRF export: header lines, column names, a unit line, rows."""
    head = ["Units: Ratio", "Ref Chan:Resp Chan\t0-Z:0-Z", "Channel Name\t : ",
            "Channel Comment\t : ", "", "Frequency\t Real\t Imaginary", "", "Units:",
            f"Hz\t{unit}\t "]
    rows = [f"{f:.13e}\t{v.real:16.7g}\t{v.imag:16.7g}" for f, v in zip(FREQ, h)]
    return "\r\n".join(head + rows) + "\r\n"


def write_export(path: Path, h: np.ndarray, **kw: str) -> Path:
    data = signalcalc_text(h, **kw).encode("latin-1")
    if path.name.lower().endswith(".gz"):
        with gzip.open(path, "wb") as fh:
            fh.write(data)
    else:
        path.write_bytes(data)
    return path


@pytest.mark.parametrize("name", ["H1.txt", "H1.txt.gz", "H1.TXT.GZ", "H1.csv.gz"])
def test_a_signalcalc_export_is_read_as_it_is(tmp_path, name):
    h = frf(1)
    data = read_any(write_export(tmp_path / name, h))
    np.testing.assert_allclose(data.frequency, FREQ)
    np.testing.assert_allclose(data.frf[:, 0, 0], h, rtol=1e-6)
    assert data.quantity == "acceleration"  # from the unit line (m/s²)(N), in Latin-1
    assert "m/s²" in data.attributes["quantity_source"]
    assert "line 9" in data.attributes["quantity_source"]
    assert data.attributes["csv_columns"] == "real, imaginary (from the header)"
    assert "before the data left out" in data.attributes["csv_preamble"]


@pytest.mark.parametrize(("unit", "quantity"), [
    ("(m/s)(N)", "velocity"), ("m/N", "displacement"), ("m/s^2/N", "acceleration"),
    ("Ratio", "displacement")])
def test_the_unit_line_gives_the_quantity(tmp_path, unit, quantity):
    data = read_csv(write_export(tmp_path / "h.txt", frf(2), unit=unit))
    assert data.quantity == quantity
    if unit == "Ratio":
        assert data.attributes["quantity_source"].startswith("not stated")


def test_a_quantity_comment_wins_over_the_unit_line(tmp_path):
    path = tmp_path / "h.txt"
    path.write_text("# quantity: velocity\n" + signalcalc_text(frf(3)), encoding="latin-1")
    assert read_csv(path).quantity == "velocity"


def test_the_column_header_among_title_lines_still_decides_the_pairs(tmp_path):
    """A magnitude/phase export with title lines is read by its column names, not as
    real/imaginary (item 1 must hold behind a preamble too)."""
    h = frf(4)
    rows = [f"{f},{abs(v)},{np.degrees(np.angle(v))}" for f, v in zip(FREQ, h)]
    path = tmp_path / "mp.csv"
    path.write_text("Test: beam\nDate: 2024-05-01\nf,tip_mag,tip_phase_deg\n" + "\n".join(rows))
    data = read_csv(path)
    np.testing.assert_allclose(data.frf[:, 0, 0], h, rtol=1e-9)
    assert data.output_names == ["tip"]


@pytest.mark.parametrize(("content", "words"), [
    (b"\x1f\x8b\x08\x00garbage", ["not a readable gzip file"]),
    (None, ["not a text file"]),
])
def test_a_broken_gzip_or_binary_text_is_one_line(tmp_path, content, words):
    path = tmp_path / "h.txt.gz"
    path.write_bytes(content if content is not None else gzip.compress(b"1\x00 2 3\n"))
    with pytest.raises(InputError) as info:
        read_any(path)
    assert "\n" not in str(info.value) and str(path) in str(info.value)
    assert all(w in str(info.value) for w in words)


def test_reader_suffix():
    assert reader_suffix("a/b.TXT.gz") == ".txt.gz"
    assert reader_suffix("run.v2.h5") == ".h5"
    assert reader_suffix("noext") == ""


def test_stacking_one_file_per_hammer_point_or_sensor(tmp_path):
    parts = [read_any(write_export(tmp_path / f"Hxysv{k:05d}.txt.gz", frf(k))) for k in (1, 2, 3)]
    hammer = stack_frfs(parts, "inputs")
    assert hammer.frf.shape == (FREQ.size, 1, 3)
    assert hammer.input_names == ["Hxysv00001", "Hxysv00002", "Hxysv00003"]
    np.testing.assert_array_equal(hammer.frf[:, 0, 1], parts[1].frf[:, 0, 0])
    sensor = stack_frfs(parts, "outputs")
    assert sensor.frf.shape == (FREQ.size, 3, 1) and sensor.output_names[2] == "Hxysv00003"
    assert sensor.quantity == "acceleration"


def test_stacking_refuses_files_that_are_not_one_test(tmp_path):
    a = read_any(write_export(tmp_path / "a.txt", frf(1)))
    b = read_any(write_export(tmp_path / "b.txt", frf(2), unit="(m/s)(N)"))
    with pytest.raises(InputError, match="quantity is velocity"):
        stack_frfs([a, b], "inputs")
    shorter = tmp_path / "c.txt"
    shorter.write_text("\n".join(signalcalc_text(frf(3)).splitlines()[:-5]), encoding="latin-1")
    with pytest.raises(InputError, match="frequency lines differ"):
        stack_frfs([a, read_any(shorter)], "inputs")


def cli(*args: object) -> subprocess.CompletedProcess:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run([sys.executable, "-m", "automodal", *map(str, args)],
                          capture_output=True, text=True, env=env, timeout=300)


def test_convert_several_files_into_one_test(tmp_path):
    files = [write_export(tmp_path / f"Hxysv{k:05d}.txt.gz", frf(k)) for k in (1, 2, 3)]
    out = tmp_path / "beam.h5"
    refused = cli("convert", *files, out)
    assert refused.returncode == 2 and "--stack inputs" in refused.stderr
    assert refused.stderr.count("\n") == 1 and not out.exists()
    done = cli("convert", *files, out, "--stack", "inputs")
    assert done.returncode == 0, done.stderr
    assert "1 output(s) x 3 input(s), acceleration" in done.stdout
    data = read_frf(out)
    assert data.input_names == ["Hxysv00001", "Hxysv00002", "Hxysv00003"]
    np.testing.assert_allclose(data.frf[:, 0, 2], frf(3), rtol=1e-6)


def test_a_batch_folder_leaves_out_a_readme_and_says_so(tmp_path):
    folder = tmp_path / "incoming"
    folder.mkdir()
    write_export(folder / "run1.txt.gz", frf(1))
    (folder / "readme.txt").write_text("Beam tests, May 2024.\nHammer: PCB 086C03, 10 hits.\n")
    (folder / "notes.csv").write_text("who,what\nAnna,hammer\n")
    left: list[Path] = []
    assert expand_inputs(str(folder), left_out=left) == [folder / "run1.txt.gz"]
    assert left == [folder / "notes.csv", folder / "readme.txt"]
    assert holds_number_rows(folder / "run1.txt.gz")
    run = cli("identify", folder, "-o", tmp_path / "out", "--bootstrap", "10")
    assert "left out 2 text file(s) without a row of numbers: notes.csv, readme.txt" in run.stderr
    assert "1 files: 1 ok" in run.stdout, run.stdout + run.stderr


@pytest.mark.realdata
@pytest.mark.skipif(not (REALDATA / "modelab_beam").is_dir(), reason="no real data")
def test_modelab_signalcalc_files_convert_in_one_command(tmp_path):
    files = sorted((REALDATA / "modelab_beam").glob("Hxysv*.txt.gz"))
    out = tmp_path / "modelab.h5"
    done = cli("convert", *files, out, "--stack", "inputs")
    assert done.returncode == 0, done.stderr
    assert "1 output(s) x 9 input(s), acceleration, 51201 lines [0, 1000] Hz" in done.stdout
