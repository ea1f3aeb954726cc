"""Readers of foreign formats (UFF/UNV dataset 58, CSV, NPZ), ``read_any`` and ``convert``."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import pyuff

from automodal.app.run import read_input
from automodal.errors import InputError
from automodal.frfdata import FRFData
from automodal.io.frf_file import read_frf, write_frf
from automodal.io.readers import read_any
from automodal.io.tabular import read_csv, read_npz
from automodal.io.uff import direction_name, read_uff

REALDATA = Path(__file__).parents[1].parent / "shared" / "realdata"
FREQ = np.arange(1.0, 41.0)  # 40 lines, 1..40 Hz


def frf_values(seed: int, n: int = FREQ.size) -> np.ndarray:
    """An arbitrary complex FRF of ``n`` lines."""
    rng = np.random.default_rng(seed)
    return rng.standard_normal(n) + 1j * rng.standard_normal(n)


def uff_set(rsp: tuple[int, int], ref: tuple[int, int], data: np.ndarray,
            x: np.ndarray = FREQ, **fields: Any) -> dict[str, Any]:
    """A dataset 58 dict: response (node, dir) per reference (node, dir); accelerance."""
    options: dict[str, Any] = {
        "binary": 0, "func_type": 4, "abscissa_spacing": 1, "abscissa_spec_data_type": 18,
        "ordinate_spec_data_type": 12, "orddenom_spec_data_type": 13,
    }
    options.update(fields)
    return pyuff.prepare_58(rsp_node=rsp[0], rsp_dir=rsp[1], ref_node=ref[0], ref_dir=ref[1],
                            data=data, x=np.asarray(x, dtype=float), **options)


def write_uff(path: Path, sets: list[dict[str, Any]]) -> Path:
    """Write the sets with pyuff into a new file.

    Always in "add" mode: pyuff's "overwrite" mode loses the ASCII header of a binary set.
    """
    path.unlink(missing_ok=True)
    pyuff.UFF(str(path)).write_sets(sets, mode="add")
    return path


def refused(reader, path: Path, *words: str) -> str:
    """Call ``reader(path)``, expect a one-line InputError naming the file and ``words``."""
    with pytest.raises(InputError) as info:
        reader(path)
    message = str(info.value)
    assert "\n" not in message
    assert str(path) in message
    for word in words:
        assert word in message, message
    return message


# ------------------------------------------------------------------------------- UFF


def test_uff_cut_inside_a_data_set_is_refused(tmp_path):
    """pyuff dropped a set cut short (a copy interrupted mid-file), and its channel with it."""
    whole = write_uff(tmp_path / "whole.uff", [
        uff_set((k, 3), (1, 3), frf_values(k)) for k in (1, 2)])
    text = whole.read_bytes()
    cut = tmp_path / "cut.uff"
    cut.write_bytes(text[: int(0.8 * len(text))])
    refused(read_uff, cut, "truncated")
    assert read_uff(whole).frf.shape[1] == 2


@pytest.mark.parametrize("label", ["rad/s", "RPM", "kHz"])
def test_uff_frequency_axis_not_in_hz_is_refused(tmp_path, label):
    path = write_uff(tmp_path / "units.uff", [
        uff_set((1, 3), (1, 3), frf_values(0), abscissa_axis_units_lab=label)])
    refused(read_uff, path, "data set 1", "not in Hz")


def test_uff_roving_hammer(tmp_path):
    values = [frf_values(j) for j in range(3)]
    path = write_uff(tmp_path / "hammer.uff",
                     [uff_set((7, 3), (j + 1, -3), values[j]) for j in range(3)])

    data = read_uff(path)

    assert data.frf.shape == (FREQ.size, 1, 3)
    np.testing.assert_allclose(data.frequency, FREQ)
    for j in range(3):
        np.testing.assert_allclose(data.frf[:, 0, j], values[j], rtol=1e-10)
    assert data.quantity == "acceleration"
    assert "ordinate data type 12" in data.attributes["quantity_source"]
    assert data.attributes["source_format"] == "UFF dataset 58 (ASCII)"
    assert data.output_nodes.tolist() == [7]
    assert data.input_nodes.tolist() == [1, 2, 3]
    assert data.output_directions == ["+Z"]
    assert data.input_directions == ["-Z", "-Z", "-Z"]
    assert data.output_names == ["7+Z"]
    assert data.input_names == ["1-Z", "2-Z", "3-Z"]
    assert data.source == str(path)


def test_uff_roving_sensor(tmp_path):
    path = write_uff(tmp_path / "sensor.uff",
                     [uff_set((i + 1, 2), (9, 1), frf_values(i)) for i in range(3)])

    data = read_uff(path)

    assert data.frf.shape == (FREQ.size, 3, 1)
    assert data.output_directions == ["+Y", "+Y", "+Y"]
    assert data.input_directions == ["+X"]


def mimo_sets(binary: int = 0) -> tuple[list[dict[str, Any]], dict[tuple[int, int], np.ndarray]]:
    """A 2x2 test, written in a shuffled order, with channel entity names."""
    outputs, inputs = [(11, 3), (12, -2)], [(21, 3), (22, 1)]
    names = {(11, 3): "acc11", (12, -2): "acc12", (21, 3): "shakerA", (22, 1): "shakerB"}
    expected, sets = {}, []
    for i, j in [(1, 0), (0, 1), (1, 1), (0, 0)]:
        expected[i, j] = frf_values(10 * i + j)
        rsp, ref = outputs[i], inputs[j]
        sets.append(uff_set(rsp, ref, expected[i, j], binary=binary,
                            rsp_ent_name=names[rsp], ref_ent_name=names[ref]))
    return sets, expected


@pytest.mark.parametrize("binary", [0, 1], ids=["ascii", "binary"])
def test_uff_mimo_2x2(tmp_path, binary):
    sets, expected = mimo_sets(binary)
    path = write_uff(tmp_path / "mimo.unv", sets)

    data = read_uff(path)

    assert data.frf.shape == (FREQ.size, 2, 2)
    # channels in order of first appearance: output 12 first, input 21 first
    assert data.output_names == ["acc12", "acc11"]
    assert data.input_names == ["shakerA", "shakerB"]
    assert data.output_nodes.tolist() == [12, 11]
    assert data.output_directions == ["-Y", "+Z"]
    assert data.input_directions == ["+Z", "+X"]
    row = {1: 0, 0: 1}  # written output index -> read output index
    for (i, j), values in expected.items():
        np.testing.assert_allclose(data.frf[:, row[i], j], values, rtol=1e-10)
    kind = "binary" if binary else "ASCII"
    assert data.attributes["source_format"] == f"UFF dataset 58 ({kind})"


def test_uff_ascii_and_binary_sets_in_one_file(tmp_path):
    sets = [uff_set((1, 3), (j + 1, 3), frf_values(j), binary=j % 2) for j in range(3)]
    data = read_uff(write_uff(tmp_path / "mixed.uff", sets))
    assert data.frf.shape == (FREQ.size, 1, 3)
    assert data.attributes["source_format"] == "UFF dataset 58 (ASCII and binary)"


def test_uff_skips_other_datasets(tmp_path):
    nodes = pyuff.prepare_15(node_nums=[1, 2], def_cs=[0, 0], disp_cs=[0, 0], color=[0, 0],
                             x=[0.0, 1.0], y=[0.0, 0.0], z=[0.0, 0.0])
    path = write_uff(tmp_path / "with_geometry.uff",
                     [nodes, uff_set((1, 3), (2, 3), frf_values(0))])
    assert read_uff(path).frf.shape == (FREQ.size, 1, 1)


def test_uff_uneven_but_identical_spacing_is_accepted(tmp_path):
    x = np.array([1.0, 1.5, 2.5, 4.0, 6.0, 8.5])
    sets = [uff_set((1, 1), (j + 1, 1), frf_values(j, x.size), x=x, abscissa_spacing=0)
            for j in range(2)]
    data = read_uff(write_uff(tmp_path / "uneven.uff", sets))
    np.testing.assert_allclose(data.frequency, x)


def test_direction_names():
    assert [direction_name(c) for c in (1, -1, 2, -3, 4, -6, 0)] == [
        "+X", "-X", "+Y", "-Z", "+RX", "-RZ", "scalar"]


@pytest.mark.parametrize(
    ("fields", "quantity", "source_word"),
    [
        ({"ordinate_spec_data_type": 11}, "velocity", "ordinate data type 11"),
        ({"ordinate_spec_data_type": 8}, "displacement", "ordinate data type 8"),
        ({"ordinate_spec_data_type": 0, "ordinate_axis_units_lab": "m/s^2"}, "acceleration",
         "label"),
        ({"ordinate_spec_data_type": 0, "ordinate_axis_units_lab": "m/s"}, "velocity", "label"),
        ({"ordinate_spec_data_type": 0, "ordinate_axis_units_lab": "mm/N"}, "displacement",
         "label"),
        ({"ordinate_spec_data_type": 0, "id1": "Mobility H12"}, "velocity", "ID line 1"),
        ({"ordinate_spec_data_type": 0}, "displacement", "not stated"),
        ({"ordinate_spec_data_type": 1, "orddenom_spec_data_type": 0}, "displacement",
         "not stated"),
    ],
)
def test_uff_quantity(tmp_path, fields, quantity, source_word):
    path = write_uff(tmp_path / "q.uff", [uff_set((1, 3), (2, 3), frf_values(0), **fields)])
    data = read_uff(path)
    assert data.quantity == quantity
    assert source_word in data.attributes["quantity_source"]


def test_uff_quantity_stated_by_some_sets_only(tmp_path):
    sets = [uff_set((1, 3), (1, 3), frf_values(0), ordinate_spec_data_type=0),
            uff_set((1, 3), (2, 3), frf_values(1), ordinate_spec_data_type=11)]
    data = read_uff(write_uff(tmp_path / "some.uff", sets))
    assert data.quantity == "velocity"
    assert "1 of 2 sets do not say" in data.attributes["quantity_source"]


def test_uff_drops_placeholder_dc_line(tmp_path):
    x = np.arange(0.0, 20.0)
    first = frf_values(0, x.size)
    first[0] = 0.0
    second = frf_values(1, x.size)
    sets = [uff_set((1, 3), (1, 3), first, x=x), uff_set((1, 3), (2, 3), second, x=x)]
    data = read_uff(write_uff(tmp_path / "dc.uff", sets))
    assert data.n_freq == x.size - 1
    assert data.frequency[0] == 1.0
    assert "0 Hz line was dropped" in data.attributes["dropped_0hz_line"]


def test_uff_drops_nan_at_dc_but_refuses_nan_elsewhere(tmp_path):
    x = np.arange(0.0, 8.0)
    path = write_uff(tmp_path / "nan.uff", [uff_set((1, 3), (1, 3), frf_values(0, x.size), x=x)])
    lines = path.read_text().splitlines()
    first_data = 13  # "-1", "58", 5 ID lines, records 6 to 11
    nan = f"{'nan':>20}"
    lines[first_data] = nan + lines[first_data][20:]  # real part at 0 Hz
    path.write_text("\n".join(lines) + "\n")
    data = read_uff(path)
    assert data.frequency[0] == 1.0 and np.all(np.isfinite(data.frf))

    lines[first_data + 1] = nan + lines[first_data + 1][20:]  # real part at 2 Hz
    path.write_text("\n".join(lines) + "\n")
    refused(read_uff, path, "non-finite")


@pytest.mark.parametrize(("func_type", "name"),
                         [(1, "time response"), (2, "auto spectrum"), (3, "cross spectrum"),
                          (6, "coherence")])
def test_uff_refuses_non_frf_function_types(tmp_path, func_type, name):
    sets = [uff_set((1, 3), (1, 3), frf_values(0)),
            uff_set((1, 3), (2, 3), frf_values(1), func_type=func_type)]
    path = write_uff(tmp_path / "spectra.uff", sets)
    refused(read_uff, path, f"function type {func_type} ({name})", "data set 2")


def test_uff_refuses_mixed_abscissas(tmp_path):
    sets = [uff_set((1, 3), (1, 3), frf_values(0)),
            uff_set((1, 3), (2, 3), frf_values(1), x=FREQ * 2)]
    refused(read_uff, write_uff(tmp_path / "axes.uff", sets), "different frequency axis")


def test_uff_refuses_different_line_counts(tmp_path):
    sets = [uff_set((1, 3), (1, 3), frf_values(0)),
            uff_set((1, 3), (2, 3), frf_values(1, 30), x=FREQ[:30])]
    refused(read_uff, write_uff(tmp_path / "lines.uff", sets), "different frequency axis")


def test_uff_refuses_real_data(tmp_path):
    sets = [uff_set((1, 3), (1, 3), frf_values(0).real)]
    refused(read_uff, write_uff(tmp_path / "real.uff", sets), "real values", "complex")


def test_uff_refuses_missing_pair(tmp_path):
    sets, _ = mimo_sets()
    refused(read_uff, write_uff(tmp_path / "holes.uff", sets[:3]),
            "1 of the 4 (output, input) pairs have no FRF")


def test_uff_refuses_duplicate_pair(tmp_path):
    sets = [uff_set((1, 3), (2, 3), frf_values(0)), uff_set((1, 3), (2, 3), frf_values(1))]
    refused(read_uff, write_uff(tmp_path / "twice.uff", sets), "data sets 1 and 2")


def test_uff_refuses_motion_per_motion(tmp_path):
    sets = [uff_set((1, 3), (2, 3), frf_values(0), orddenom_spec_data_type=12)]
    refused(read_uff, write_uff(tmp_path / "transmissibility.uff", sets), "not per unit force")


def test_uff_refuses_file_without_dataset_58(tmp_path):
    nodes = pyuff.prepare_15(node_nums=[1], def_cs=[0], disp_cs=[0], color=[0],
                             x=[0.0], y=[0.0], z=[0.0])
    refused(read_uff, write_uff(tmp_path / "geometry.uff", [nodes]), "no dataset 58", "15")
    text = tmp_path / "text.uff"
    text.write_text("this is not a universal file\n")
    refused(read_uff, text, "no dataset 58")


def test_uff_pyuff_error_becomes_input_error(tmp_path):
    bad = tmp_path / "broken.uff"
    bad.write_text("    -1\n    58\nonly a few lines\n    -1\n")
    refused(read_uff, bad, "cannot read data set 1")


def test_uff_refuses_missing_file(tmp_path):
    refused(read_uff, tmp_path / "absent.uff", "no such file")


# ------------------------------------------------------------------------------- CSV


def write_table(path: Path, frf: np.ndarray, header: str | None = None, sep: str = ",",
                comments: str = "") -> Path:
    """Write frequency + real/imag pairs of ``frf`` (lines x outputs) as a table."""
    columns = [FREQ]
    for i in range(frf.shape[1]):
        columns += [frf[:, i].real, frf[:, i].imag]
    rows = [sep.join(repr(float(v)) for v in row) for row in np.column_stack(columns)]
    lines = ([comments] if comments else []) + ([header] if header else []) + rows
    path.write_text("\n".join(lines) + "\n")
    return path


def two_frfs() -> np.ndarray:
    """Two FRFs as a (lines, 2) complex array."""
    return np.column_stack([frf_values(1), frf_values(2)])


def test_csv_round_trip_with_header(tmp_path):
    frf = two_frfs()
    path = write_table(tmp_path / "t.csv", frf, header="f_Hz,tip_re,tip_im,Re(root),Im(root)")
    data = read_csv(path)
    assert data.frf.shape == (FREQ.size, 2, 1)
    np.testing.assert_array_equal(data.frequency, FREQ)
    np.testing.assert_array_equal(data.frf[:, :, 0], frf)
    assert data.output_names == ["tip", "root"]
    assert data.input_names == ["u1"]
    assert data.quantity == "displacement"
    assert data.attributes["quantity_source"].startswith("not stated")


@pytest.mark.parametrize(
    ("header", "encode"),
    [
        ("f,tip_mag,tip_phase_deg", lambda h: (np.abs(h), np.degrees(np.angle(h)))),
        ("f,Magnitude [m/N],Phase (rad)", lambda h: (np.abs(h), np.angle(h))),
        ("f,tip dB,tip phase deg", lambda h: (20 * np.log10(np.abs(h)),
                                             np.degrees(np.angle(h)))),
    ],
    ids=["mag-deg", "mag-rad", "db-deg"],
)
def test_csv_magnitude_and_phase_columns_are_read_by_their_header(tmp_path, header, encode):
    """Issue 15, item 1: a (magnitude, phase) table is not read as (real, imaginary)."""
    h = frf_values(1)
    a, b = encode(h)
    path = tmp_path / "m.csv"
    path.write_text(header + "\n" + "\n".join(
        f"{float(f)!r},{float(x)!r},{float(y)!r}" for f, x, y in zip(FREQ, a, b)) + "\n")
    data = read_csv(path)
    np.testing.assert_allclose(data.frf[:, 0, 0], h, rtol=1e-12)
    assert "phase" in data.attributes["csv_columns"]
    assert data.output_names[0] in ("tip", "y1")


@pytest.mark.parametrize(
    ("header", "words"),
    [
        ("f,mag,phase", ["phase's unit is not stated", "phase_deg"]),
        ("f,tip_mag,tip_im", ["not a (real, imaginary), (magnitude, phase)"]),
        ("f,tip_re,tip_phase_deg", ["not a (real, imaginary)"]),
    ],
    ids=["no-unit", "mag-im", "re-phase"],
)
def test_csv_header_pairs_that_cannot_be_read_safely_are_refused(tmp_path, header, words):
    path = tmp_path / "bad.csv"
    path.write_text(header + "\n1,2,3\n2,2,4\n")
    refused(read_csv, path, *words)


def test_csv_negative_magnitude_is_refused(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("f,mag,phase_deg\n1,-20,3\n2,-21,4\n")
    refused(read_csv, path, "negative magnitude", "dB")


def test_csv_whitespace_without_header_with_quantity_comment(tmp_path):
    frf = two_frfs()
    path = write_table(tmp_path / "t.txt", frf, sep="\t ", comments="# quantity: velocity")
    data = read_csv(path)
    np.testing.assert_array_equal(data.frf[:, :, 0], frf)
    assert data.output_names == ["y1", "y2"]
    assert data.quantity == "velocity"
    assert "comment" in data.attributes["quantity_source"]


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("1,2,3,4\n2,2,3,4\n", ["4 columns", "odd number"]),
        ("1,2\n2,3\n", ["2 columns"]),
        ("1,2,3\n2,x,3\n", ["line 2", "'x' is not a number"]),
        ("1,2,3\n2,2\n", ["line 2 has 2 columns"]),
        ("1;2;3\n2;2;3\n", ["not a number"]),
        ("# nothing\n\n", ["no data rows"]),
        ("f,re,im\n", ["a header but no data rows"]),
        ("f,a_re,a_im,b_re\n1,2,3\n", ["header has 4 columns"]),
        ("1,2,0\n2,3,0\n", ["imaginary part", "zero"]),
        ("2,2,1\n1,3,1\n", ["not strictly increasing"]),
        ("-1,2,1\n1,3,1\n", ["negative"]),
        ("1,nan,1\n2,3,1\n", ["non-finite"]),
        ("# quantity: force\n1,2,1\n2,3,1\n", ["unknown quantity 'force'"]),
    ],
    ids=["even-columns", "too-few", "word", "ragged", "semicolons", "empty", "header-only",
         "header-length", "real", "decreasing", "negative", "nan", "quantity"],
)
def test_csv_refusals(tmp_path, text, words):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    refused(read_csv, path, *words)


@pytest.mark.parametrize(
    "name", ["frequency (kHz)", "freq_kHz", "f [rad/s]", "omega", "frequency (rpm)"])
def test_csv_frequency_column_not_in_hz_is_refused(tmp_path, name):
    """Read as Hz, such a column moved every mode by its unit's factor, without a word."""
    path = tmp_path / "units.csv"
    path.write_text(f"{name},H_re,H_im\n1,2,3\n2,2,4\n")
    refused(read_csv, path, "not in Hz", "convert them to Hz")
    refused(read_any, path, "not in Hz")


@pytest.mark.parametrize("name", ["frequency", "Frequency (Hz)", "freq_Hz", "f [Hz]", "Hz"])
def test_csv_frequency_column_in_hz_is_read(tmp_path, name):
    path = tmp_path / "units.csv"
    path.write_text(f"{name},H_re,H_im\n1,2,3\n2,2,4\n")
    np.testing.assert_array_equal(read_csv(path).frequency, [1.0, 2.0])


def test_csv_refuses_binary_file(tmp_path):
    path = tmp_path / "bin.csv"
    path.write_bytes(b"\xff\xfe\x00\x81binary")
    refused(read_csv, path, "not a text file (UTF-8 or Latin-1)")


# ------------------------------------------------------------------------------- NPZ


def test_npz_round_trip_3d(tmp_path):
    rng = np.random.default_rng(3)
    frf = rng.standard_normal((FREQ.size, 3, 2)) + 1j * rng.standard_normal((FREQ.size, 3, 2))
    path = tmp_path / "t.npz"
    np.savez(path, frequency=FREQ, frf=frf, quantity="acceleration", note=np.arange(2))
    data = read_npz(path)
    np.testing.assert_array_equal(data.frequency, FREQ)
    np.testing.assert_array_equal(data.frf, frf)
    assert data.quantity == "acceleration"
    assert data.attributes["ignored_keys"] == "note"
    assert "'quantity' key" in data.attributes["quantity_source"]


def test_npz_2d_is_one_input(tmp_path):
    frf = two_frfs()
    path = tmp_path / "t.npz"
    np.savez(path, frequency=FREQ, frf=frf)
    data = read_npz(path)
    assert data.frf.shape == (FREQ.size, 2, 1)
    np.testing.assert_array_equal(data.frf[:, :, 0], frf)
    assert data.quantity == "displacement"
    assert data.attributes["quantity_source"].startswith("not stated")


@pytest.mark.parametrize(
    ("arrays", "words"),
    [
        ({"frequency": FREQ, "frf": frf_values(0).real[:, None]}, ["not complex"]),
        ({"frequency": FREQ, "frf": frf_values(0)}, ["shape (40,)", "expected keys"]),
        ({"frequency": FREQ}, ["no key 'frf'", "keys found: frequency"]),
        ({"frf": two_frfs()}, ["no key 'frequency'"]),
        ({"frequency": FREQ, "frf": two_frfs().T}, ["transposed"]),
        ({"frequency": FREQ[:-1], "frf": two_frfs()}, ["first axis"]),
        ({"frequency": FREQ, "frf": two_frfs(), "quantity": "force"}, ["unknown quantity"]),
        ({"frequency": FREQ, "frf": two_frfs(), "quantity": np.array(["a", "b"])},
         ["must be one string"]),
        ({"frequency": FREQ.astype(complex), "frf": two_frfs()}, ["real numbers"]),
        ({"frequency": FREQ[::-1], "frf": two_frfs()}, ["not strictly increasing"]),
    ],
    ids=["real", "1-D", "no-frf", "no-frequency", "transposed", "length", "quantity",
         "quantity-array", "complex-frequency", "decreasing"],
)
def test_npz_refusals(tmp_path, arrays, words):
    path = tmp_path / "bad.npz"
    np.savez(path, **arrays)
    refused(read_npz, path, *words)


def test_npz_refuses_pickles_and_non_archives(tmp_path):
    pickled = tmp_path / "obj.npz"
    np.savez(pickled, frequency=FREQ, frf=np.array([{"a": 1}], dtype=object))
    refused(read_npz, pickled, "cannot read as an .npz archive")
    text = tmp_path / "text.npz"
    text.write_text("hello")
    refused(read_npz, text, "cannot read as an .npz archive")
    single = tmp_path / "single.npz"
    with open(single, "wb") as f:
        np.save(f, FREQ)
    refused(read_npz, single, "single .npy array")


# --------------------------------------------------------------------------- read_any


def sample_data() -> FRFData:
    """A small valid test for HDF5 files."""
    return FRFData(frequency=FREQ, frf=two_frfs()[:, :, None], quantity="velocity")


def test_read_any_chooses_by_suffix(tmp_path):
    uff = write_uff(tmp_path / "a.UFF", [uff_set((1, 3), (2, 3), frf_values(0))])
    csv = write_table(tmp_path / "a.csv", two_frfs())
    npz = tmp_path / "a.npz"
    np.savez(npz, frequency=FREQ, frf=two_frfs())
    h5 = tmp_path / "a.hdf5"
    write_frf(h5, sample_data())
    assert read_any(uff).attributes["source_format"].startswith("UFF")
    assert read_any(csv).attributes["source_format"] == "CSV table"
    assert read_any(npz).attributes["source_format"] == "NPZ archive"
    assert read_any(h5).quantity == "velocity"


def test_read_any_unknown_suffix(tmp_path):
    h5 = tmp_path / "test.frf"
    write_frf(h5, sample_data())
    assert read_any(h5).frf.shape == (FREQ.size, 2, 1)
    other = tmp_path / "test.dat"
    other.write_text("1 2 3\n")
    refused(read_any, other, "unknown input type")
    refused(read_any, tmp_path / "missing.uff", "no such file")
    refused(read_any, tmp_path, "is a folder")


def test_identify_read_input_uses_read_any(tmp_path):
    uff = write_uff(tmp_path / "a.uff", [uff_set((1, 3), (2, 3), frf_values(0))])
    assert read_input(str(uff)).attributes["source_format"] == "UFF dataset 58 (ASCII)"
    with pytest.raises(InputError, match="is a folder"):
        read_input(str(tmp_path))


# ---------------------------------------------------------------------------- convert


def run_convert(*args: str) -> subprocess.CompletedProcess:
    """``python -m automodal convert ARGS`` in a fresh process."""
    command = [sys.executable, "-m", "automodal", "convert", *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=120)


def assert_same_data(read: FRFData, source: FRFData) -> None:
    """Everything ``convert`` keeps is equal."""
    np.testing.assert_array_equal(read.frequency, source.frequency)
    np.testing.assert_array_equal(read.frf, source.frf)
    assert read.quantity == source.quantity
    assert read.output_names == source.output_names
    assert read.input_names == source.input_names
    assert read.output_directions == source.output_directions
    assert read.input_directions == source.input_directions
    for got, want in [(read.output_nodes, source.output_nodes),
                      (read.input_nodes, source.input_nodes)]:
        assert (got is None) == (want is None)
        if want is not None:
            np.testing.assert_array_equal(got, want)
    assert read.attributes == source.attributes


def test_convert_uff_round_trip(tmp_path):
    sets, _ = mimo_sets()
    uff = write_uff(tmp_path / "mimo.uff", sets)
    out = tmp_path / "mimo.h5"

    result = run_convert(str(uff), str(out))

    assert result.returncode == 0, result.stderr
    assert result.stderr == ""
    assert result.stdout.splitlines() == [
        f"{out}: 2 output(s) x 2 input(s), acceleration, 40 lines [1, 40] Hz"]
    assert_same_data(read_frf(out), read_uff(uff))


def test_convert_csv_quiet(tmp_path):
    csv = write_table(tmp_path / "t.csv", two_frfs())
    out = tmp_path / "t.h5"
    result = run_convert(str(csv), str(out), "--quiet")
    assert result.returncode == 0, result.stderr
    assert result.stdout == ""
    assert_same_data(read_frf(out), read_csv(csv))


def test_convert_time_series_writes_their_frfs(tmp_path):
    import json

    from automodal.io.time_file import read_time, write_time
    from automodal.pipeline import input_stage
    from automodal.timedata import TimeSeries

    source = tmp_path / "time.h5"
    outputs = np.random.default_rng(4).standard_normal((2048, 2))
    write_time(source, TimeSeries(outputs, None, 256.0, attributes={"quantity": "velocity"}))
    out = tmp_path / "frf.h5"
    result = run_convert(str(source), str(out), "--quiet")
    assert result.returncode == 0, result.stderr
    read, made = read_frf(out), input_stage(read_time(source))  # what identify analyses
    np.testing.assert_array_equal(read.frf, made.frf)
    assert read.quantity == "velocity" and read.attributes["analysis"] == "operational"
    assert read.attributes["window_decay_per_s"] == made.attributes["window_decay_per_s"]
    assert json.loads(read.attributes["time_analysis"]) == made.attributes["time_analysis"]


def test_convert_summary_says_assumed_quantity(tmp_path):
    csv = write_table(tmp_path / "t.csv", two_frfs())
    result = run_convert(str(csv), str(tmp_path / "t.h5"))
    assert result.returncode == 0, result.stderr
    assert "displacement (assumed: not stated in the input)" in result.stdout


@pytest.mark.parametrize("case", ["bad-input", "bad-suffix", "folder-is-a-file"])
def test_convert_refusals(tmp_path, case):
    good = write_uff(tmp_path / "good.uff", [uff_set((1, 3), (2, 3), frf_values(0))])
    bad = write_uff(tmp_path / "bad.uff", [uff_set((1, 3), (2, 3), frf_values(0), func_type=2)])
    source, out, name = {
        "bad-input": (bad, tmp_path / "out.h5", "bad.uff"),
        "bad-suffix": (good, tmp_path / "out.json", "out.json"),
        # a missing folder is made; one that cannot be (a file in its place) is refused
        "folder-is-a-file": (good, tmp_path / "good.uff" / "out.h5", "out.h5"),
    }[case]

    result = run_convert(str(source), str(out))

    assert result.returncode == 2, result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("automodal: error: "), result.stderr
    assert name in lines[0]
    assert result.stdout == ""
    assert not out.exists()
    assert not any(p.name.startswith(".out") for p in tmp_path.iterdir())


def test_convert_help_has_example():
    result = run_convert("--help")
    assert result.returncode == 0
    assert "automodal convert measurement.uff measurement.h5" in result.stdout


# ---------------------------------------------------------------------------- realdata


@pytest.mark.realdata
def test_realdata_ladisk_beam_uff():
    path = REALDATA / "ladisk_beam_frf" / "measurement.uff"
    if not path.is_file():
        pytest.skip(f"{path} is not available")
    data = read_uff(path)
    assert data.frf.shape in {(1000, 1, 3), (1001, 1, 3)}
    assert data.n_outputs == 1 and data.n_inputs == 3  # roving hammer
    assert data.quantity == "acceleration"
    assert np.all(np.isfinite(data.frf)) and np.all(np.isfinite(data.frequency))
    assert data.frequency[0] > 0  # the 0+0j placeholder line at 0 Hz is dropped
    assert data.input_nodes.tolist() == [1, 2, 3]
    assert data.output_directions == ["+X"]
