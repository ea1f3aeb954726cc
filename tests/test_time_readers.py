"""Time records in the forms labs produce (docs/time-input.md): NumPy .npy/.npz, CSV/TSV of
samples, MATLAB .mat (v5 and v7.3), NI TDMS and UFF time responses; the options
--sample-rate, --forces and --quantity; and every refusal in one line, exit 2, no report."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io
import scipy.linalg
import scipy.signal

import automodal.core.simulate as sim
from automodal.errors import InputError
from automodal.frfdata import FRFData
from automodal.io.channels import TimeOptions, rate_from_time, time_unit
from automodal.io.readers import read_any
from automodal.io.time_file import read_time, write_time
from automodal.timedata import TimeSeries

FS = 128.0
N = 8192
NAMES = ["x1", "x2", "x3"]
REALDATA = Path(__file__).resolve().parents[1].parent / "shared" / "realdata"


def system() -> sim.MechanicalSystem:
    """3-DOF chain, modes near 7, 20 and 29 Hz, 2 % damping."""
    return sim.damp(sim.chain(3, stiffness=1e4), zeta=0.02)


@pytest.fixture(scope="module")
def record() -> TimeSeries:
    """A random force at DOF 3 and the three displacements (exact zero-order hold)."""
    A, B, C, D = sim.state_space(system(), None, [2], "displacement")
    n, m = A.shape[0], B.shape[1]
    E = scipy.linalg.expm(np.block([[A, B], [np.zeros((m, n + m))]]) / FS)
    u = np.random.default_rng(7).standard_normal((N, 1))
    _, y, _ = scipy.signal.dlsim((E[:n, :n], E[:n, n:], C, D, 1.0), u)
    y = y / np.std(y, axis=0)  # order-one numbers, exactly printable
    return TimeSeries(y, u, FS, output_names=NAMES, input_names=["force"])


def samples(ts: TimeSeries) -> np.ndarray:
    """Responses then the force, (samples, 4)."""
    return np.hstack([ts.outputs, ts.inputs])


def assert_same(read: TimeSeries, ts: TimeSeries, rtol: float = 0.0) -> None:
    """The read series has the written samples, rate and split."""
    assert isinstance(read, TimeSeries)
    assert read.sample_rate == pytest.approx(ts.sample_rate, rel=1e-9)
    np.testing.assert_allclose(read.outputs, ts.outputs, rtol=rtol, atol=0)
    np.testing.assert_allclose(read.inputs, ts.inputs, rtol=rtol, atol=0)
    assert read.n_inputs == 1 and read.n_outputs == 3


def write_csv(path: Path, header: list[str], table: np.ndarray, sep: str = ",",
              comment: str = "") -> Path:
    lines = [comment] if comment else []
    lines.append(sep.join(header))
    lines += [sep.join(f"{v:.17g}" for v in row) for row in table]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


# -------------------------------------------------------------------------- round trips


def test_npy_samples_by_channels_with_rate_and_forces_by_position(tmp_path, record):
    path = tmp_path / "r.npy"
    np.save(path, samples(record))
    read = read_any(path, TimeOptions(sample_rate=FS, forces=("3",)))
    assert_same(read, record)
    assert read.output_names == ["ch0", "ch1", "ch2"] and read.input_names == ["ch3"]
    assert read.attributes["sample_rate_source"] == "--sample-rate"


def test_npy_channels_by_samples_with_a_time_row(tmp_path, record):
    """Rows time, force, responses (as the LADISK files): the time row gives the rate and
    keeps its position, so that --forces 1 is the force."""
    t = np.arange(N) / FS
    path = tmp_path / "r.npy"
    np.save(path, np.vstack([t, record.inputs.T, record.outputs.T]))
    read = read_any(path, TimeOptions(forces=("1",)))
    assert_same(read, record)
    assert "time axis" in read.attributes["sample_rate_source"]
    assert "longer axis" in read.attributes["orientation"]
    read = read_any(path, TimeOptions(sample_rate=FS, forces=("1",)))  # agrees: accepted
    assert read.sample_rate == pytest.approx(FS)


def test_npz_of_samples_with_the_files_own_split(tmp_path, record):
    path = tmp_path / "r.npz"
    np.savez(path, outputs=record.outputs, inputs=record.inputs, sample_rate=FS,
             output_names=np.array(NAMES), input_names=np.array(["force"]),
             quantity="displacement", note=np.arange(3))
    read = read_any(path)
    assert_same(read, record)
    assert read.output_names == NAMES and read.input_names == ["force"]
    assert read.attributes["quantity"] == "displacement"
    assert read.attributes["ignored_keys"] == "note"


def test_npz_of_unsplit_samples_with_names_and_a_time_vector(tmp_path, record):
    path = tmp_path / "r.npz"
    np.savez(path, data=samples(record).T, time=np.arange(N) / FS,
             channel_names=np.array([*NAMES, "force"]))
    read = read_any(path, TimeOptions(forces=("force",), quantity="displacement"))
    assert_same(read, record)
    assert read.input_names == ["force"] and read.attributes["quantity"] == "displacement"


def test_npz_of_frfs_is_still_read_as_frfs(tmp_path):
    path = tmp_path / "f.npz"
    np.savez(path, frequency=np.arange(1.0, 11.0), frf=np.ones((10, 2)) * (1 + 1j))
    assert isinstance(read_any(path), FRFData)


@pytest.mark.parametrize(("header", "unit", "sep"), [
    (["t", *NAMES, "force"], 1.0, ","),
    (["Time (s)", *NAMES, "force"], 1.0, "\t"),
    ([*NAMES, "t [ms]", "force"], 1e-3, ","),
])
def test_csv_of_samples_with_a_time_column(tmp_path, record, header, unit, sep):
    t = np.arange(N) / FS / unit
    position = header.index(next(h for h in header if time_unit(h) is not None))
    table = np.insert(samples(record), position, t, axis=1)
    path = write_csv(tmp_path / ("r.tsv" if sep == "\t" else "r.csv"), header, table, sep,
                     comment="# quantity: displacement")
    read = read_any(path, TimeOptions(forces=("force",)))
    assert_same(read, record)
    assert read.output_names == NAMES and read.attributes["quantity"] == "displacement"
    assert read.sample_rate == pytest.approx(FS, rel=1e-9)


def test_csv_of_channels_needs_the_rate_and_then_reads(tmp_path, record):
    path = write_csv(tmp_path / "r.csv", [*NAMES, "force"], samples(record))
    with pytest.raises(InputError, match="neither a frequency column"):
        read_any(path)
    assert_same(read_any(path, TimeOptions(sample_rate=FS, forces=("force",))), record)


def test_csv_of_frfs_is_still_read_as_frfs(tmp_path):
    path = write_csv(tmp_path / "f.csv", ["f", "a_re", "a_im"],
                     np.column_stack([np.arange(1.0, 6.0), np.ones(5), np.ones(5)]))
    assert isinstance(read_any(path), FRFData)


def test_mat_v5(tmp_path, record):
    path = tmp_path / "r.mat"
    scipy.io.savemat(path, {"data": samples(record), "Fs": FS,
                            "channel_names": np.array([*NAMES, "force"], dtype=object),
                            "operator": "someone"})
    read = read_any(path, TimeOptions(forces=("force",)))
    assert_same(read, record)
    assert read.output_names == NAMES and read.attributes["ignored_keys"] == "operator"


def write_mat73(path: Path, data: np.ndarray, names: list[str], fs: float) -> None:
    """A MATLAB v7.3 file as MATLAB writes it: HDF5 after a 512-byte user block, arrays
    transposed, text as uint16 characters, cells as references."""
    with h5py.File(path, "w", userblock_size=512) as f:
        f.create_dataset("data", data=data.T).attrs["MATLAB_class"] = np.bytes_("double")
        f.create_dataset("fs", data=np.array([[fs]])).attrs["MATLAB_class"] = np.bytes_("double")
        refs = f.create_group("#refs#")
        cells = []
        for i, name in enumerate(names):
            ds = refs.create_dataset(f"n{i}", data=np.array([[ord(c)] for c in name],
                                                             dtype=np.uint16))
            ds.attrs["MATLAB_class"] = np.bytes_("char")
            cells.append(ds.ref)
        ds = f.create_dataset("channel_names", data=np.array([cells], dtype=h5py.ref_dtype).T)
        ds.attrs["MATLAB_class"] = np.bytes_("cell")


def test_mat_v73(tmp_path, record):
    path = tmp_path / "r.mat"
    write_mat73(path, samples(record), [*NAMES, "force"], FS)
    read = read_any(path, TimeOptions(forces=("force",)))
    assert_same(read, record)
    assert read.output_names == NAMES


def test_tdms(tmp_path, record):
    from nptdms import ChannelObject, TdmsWriter

    path = tmp_path / "r.tdms"
    with TdmsWriter(str(path)) as writer:
        writer.write_segment([ChannelObject("test", name, samples(record)[:, i],
                                            properties={"wf_increment": 1.0 / FS})
                              for i, name in enumerate([*NAMES, "force"])])
    read = read_any(path, TimeOptions(forces=("force",)))
    assert_same(read, record)
    assert read.attributes["sample_rate_source"] == "the channels' wf_increment"


def test_uff_time_responses(tmp_path, record):
    import pyuff

    t = np.arange(N) / FS
    sets = [pyuff.prepare_58(binary=0, func_type=1, rsp_node=i + 1, rsp_dir=3, ref_node=4,
                             ref_dir=3, data=samples(record)[:, i], x=t, abscissa_spacing=1,
                             abscissa_spec_data_type=17,
                             ordinate_spec_data_type=13 if i == 3 else 8,
                             orddenom_spec_data_type=0, rsp_ent_name=name)
            for i, name in enumerate([*NAMES, "force"])]
    path = tmp_path / "r.uff"
    pyuff.UFF(str(path)).write_sets(sets, mode="add")
    read = read_any(path)
    assert_same(read, record, rtol=1e-9)  # ASCII: 12 digits
    assert read.input_names == ["force"] and read.attributes["quantity"] == "displacement"
    assert read.attributes["forces_source"] == "the file"


def test_hdf5_time_file_takes_agreeing_options_and_refuses_others(tmp_path, record):
    path = tmp_path / "r.h5"
    write_time(path, record)
    assert_same(read_any(path, TimeOptions(sample_rate=FS, forces=("force",))), record)
    with pytest.raises(InputError, match="contradicts"):
        read_any(path, TimeOptions(sample_rate=2 * FS))
    with pytest.raises(InputError, match="contradicts the file"):
        read_any(path, TimeOptions(forces=("x1",)))


def test_rate_from_time_refuses_gaps_and_accepts_printing_roundoff():
    t = np.round(np.arange(1000) / 25600.0, 6)  # 6 decimals: 2.6 % of a step
    assert rate_from_time(t, "t") == pytest.approx(25600.0, rel=1e-5)
    with pytest.raises(InputError, match="not uniformly sampled"):
        rate_from_time(np.delete(np.arange(1000.0), 500), "t")
    with pytest.raises(InputError, match="does not increase"):
        rate_from_time(np.array([0.0, 1.0, 1.0, 2.0]), "t")


# ----------------------------------------------------------------------- the command line


def run(*args: str, env_python: list[str] | None = None) -> subprocess.CompletedProcess:
    command = [*(env_python or [sys.executable, "-m", "automodal"]), *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=600)


def physical_hz(report: Path) -> np.ndarray:
    modes = json.loads(report.read_text())["modes"]
    return np.array([m["frequency_hz"] for m in modes if m["physical"]])


@pytest.mark.parametrize("form", ["csv", "npy"])
def test_identify_from_the_shell_finds_the_modes(tmp_path, record, form):
    truth = sim.natural_frequencies_hz(system())
    if form == "csv":
        path = write_csv(tmp_path / "r.csv", ["time", *NAMES, "force"],
                         np.column_stack([np.arange(N) / FS, samples(record)]))
        options = ["--forces", "force"]
    else:
        path = tmp_path / "r.npy"
        np.save(path, samples(record))
        options = ["--sample-rate", str(FS), "--forces", "3"]
    report = tmp_path / "r.json"
    result = run("identify", str(path), *options, "--bootstrap", "20", "-q", "-o", str(report))
    assert result.returncode == 0, result.stderr
    found = physical_hz(report)
    for f in truth:
        assert found.size and np.min(np.abs(found / f - 1)) < 0.01, (truth, found)
    analysis = json.loads(report.read_text())["input"]["attributes"]
    assert analysis["forces_source"] == "--forces"


def test_convert_writes_the_records_for_identifying_again(tmp_path, record):
    path = tmp_path / "r.npy"
    np.save(path, samples(record))
    out = tmp_path / "r.h5"
    result = run("convert", str(path), str(out), "--sample-rate", str(FS), "--forces", "3",
                 "--quantity", "displacement")
    assert result.returncode == 0, result.stderr
    assert "3 output(s) x 1 input(s), displacement" in result.stdout
    again = read_time(out)
    np.testing.assert_array_equal(again.outputs, record.outputs)
    np.testing.assert_array_equal(again.inputs, record.inputs)
    assert again.sample_rate == FS and again.input_names == ["ch3"]
    assert isinstance(read_any(out), FRFData)  # the FRFs, made once


def bad_npy(values: np.ndarray):
    return lambda d: np.save(d / "in.npy", values) or d / "in.npy"


def bad_csv(header: list[str], table: np.ndarray):
    return lambda d: write_csv(d / "in.csv", header, table)


def _noise(n: int = 512, c: int = 3) -> np.ndarray:
    return np.random.default_rng(0).standard_normal((n, c))


def _gappy_time() -> np.ndarray:
    t = np.delete(np.arange(513) / 100.0, 200)
    return np.column_stack([t, _noise(512, 2)])


def _with_nan() -> np.ndarray:
    x = _noise()
    x[10, 1] = np.nan
    return x


def _mat_without_samples(d: Path) -> Path:
    scipy.io.savemat(d / "in.mat", {"x": _noise(), "rate": 100.0})
    return d / "in.mat"


def _mixed_npz(d: Path) -> Path:
    np.savez(d / "in.npz", frequency=np.arange(3.0), frf=np.ones(3) * 1j, samples=_noise())
    return d / "in.npz"


def _frf_csv(d: Path) -> Path:
    return write_csv(d / "in.csv", ["f", "a_re", "a_im"], np.column_stack(
        [np.arange(1.0, 6.0), np.ones(5), np.ones(5)]))


def _tdms(d: Path) -> Path:
    from nptdms import ChannelObject, TdmsWriter

    with TdmsWriter(str(d / "in.tdms")) as writer:
        writer.write_segment([ChannelObject("g", "a", _noise(512, 1)[:, 0])])
    return d / "in.tdms"


REFUSALS = [
    ("no-sample-rate", bad_npy(_noise()), [], "--sample-rate HZ"),
    ("non-uniform-time", bad_csv(["t", "a", "b"], _gappy_time()), [], "not uniformly sampled"),
    ("ambiguous-header", bad_csv(["a", "b", "c"], _noise()), [], "neither a frequency column"),
    ("unknown-force", bad_npy(_noise()), ["--sample-rate", "100", "--forces", "acc9"],
     "names no channel"),
    ("force-position-out-of-range", bad_npy(_noise()), ["--sample-rate", "100", "--forces", "7"],
     "names no channel"),
    ("mat-no-variable", _mat_without_samples, ["--sample-rate", "100"], "variables found: rate, x"),
    ("nan-samples", bad_npy(_with_nan()), ["--sample-rate", "100"], "non-finite"),
    ("huge-samples", bad_csv(["a", "b", "c"], _noise() * 1e200), ["--sample-rate", "100"],
     "samples up to"),
    ("too-short-1d", bad_npy(np.random.default_rng(0).standard_normal(40)),
     ["--sample-rate", "100"], "too short"),
    ("rate-contradicts-time", bad_csv(["t", "a", "b"], np.column_stack(
        [np.arange(512) / 100.0, _noise(512, 2)])), ["--sample-rate", "200"], "contradicts"),
    ("square-array", bad_npy(_noise(3, 3)), ["--sample-rate", "100"], "square"),
    ("options-for-frfs", _frf_csv, ["--sample-rate", "100"], "the file holds FRFs"),
    ("force-named-channel", bad_csv(["t", "hammer force", "acc"], np.column_stack(
        [np.arange(512) / 100.0, _noise(512, 2)])), [], "named like a force"),
    ("all-forces", bad_npy(_noise(512, 1)), ["--sample-rate", "100", "--forces", "0"],
     "every channel is a force"),
    ("frf-and-samples-npz", _mixed_npz, [], "keep one kind"),
    ("dead-channel", bad_npy(np.column_stack([_noise(512, 2), np.ones(512)])),
     ["--sample-rate", "100"], "constant"),
    ("tdms-no-rate", _tdms, [], "--sample-rate HZ"),
]


@pytest.mark.parametrize(("case", "make", "options", "words"), REFUSALS,
                         ids=[r[0] for r in REFUSALS])
def test_identify_refuses_in_one_line(tmp_path, case, make, options, words):
    path = make(tmp_path)
    report = tmp_path / "r.json"
    result = run("identify", str(path), *options, "-o", str(report))
    assert result.returncode == 2, (result.stdout, result.stderr)
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("automodal: error: "), result.stderr
    assert path.name in lines[0] and words in lines[0], lines[0]
    assert not report.exists()


def test_missing_nptdms_is_one_line_naming_the_extra(tmp_path):
    path = _tdms(tmp_path)
    code = ("import sys; sys.modules['nptdms'] = None; from automodal.cli import main; "
            f"sys.argv = ['automodal', 'identify', {str(path)!r}, '--sample-rate', '100']; "
            "main(prog_name='automodal')")
    result = run(env_python=[sys.executable, "-c", code])
    assert result.returncode == 2
    assert result.stderr.splitlines() == [
        f"automodal: error: {path}: reading a .tdms file needs npTDMS: "
        "pip install 'automodal[tdms]'"]


def test_batch_refuses_time_options(tmp_path):
    result = run("identify", str(tmp_path), "-o", str(tmp_path / "out"), "--sample-rate", "100")
    assert result.returncode == 2
    assert "are for one file" in result.stderr and len(result.stderr.splitlines()) == 1


# ------------------------------------------------------------------------------ real data


@pytest.mark.realdata
@pytest.mark.skipif(not REALDATA.is_dir(), reason="../shared/realdata is absent")
def test_realdata_ladisk_impact_npy_reads_time_row_force_response():
    path = REALDATA / "ladisk_impact_timeseries" / "measurements_1.npy"
    ts = read_any(path, TimeOptions(sample_rate=25600.0, forces=("1",)))
    assert ts.sample_rate == pytest.approx(25600.0)
    assert (ts.n_samples, ts.n_outputs, ts.n_inputs) == (25600, 1, 1)
    assert ts.input_names == ["ch1"] and ts.output_names == ["ch2"]


@pytest.mark.realdata
@pytest.mark.skipif(not REALDATA.is_dir(), reason="../shared/realdata is absent")
def test_realdata_weimar_npy_reads_as_output_only_samples():
    path = REALDATA / "weimar_steel_frame" / "measurement_1" / "measurement_1.npy"
    ts = read_any(path, TimeOptions(sample_rate=256.0))
    assert (ts.n_samples, ts.n_outputs, ts.inputs) == (61440, 6, None)
    assert "orientation" not in ts.attributes


def test_a_npy_whose_header_is_damaged_is_refused(tmp_path):
    """numpy parses the header as a Python literal: a header cut by zeros raised the
    tokenizer's TokenError through the reader (found by the property-based tests)."""
    from automodal.errors import InputError
    from automodal.io.readers import read_any

    path = tmp_path / "damaged.npy"
    np.save(path, np.zeros((64, 2)))
    raw = bytearray(path.read_bytes())
    raw[40:] = bytes(len(raw) - 40)  # zeros from the middle of the header on
    path.write_bytes(bytes(raw))
    with pytest.raises(InputError):
        read_any(path)
