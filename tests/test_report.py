"""The identification report (docs/report.md): content, JSON and HDF5 files, the table."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from report_schema import assert_no_non_finite_text, assert_plain_json_types, validate_report

from automodal.core.simulate import chain, damp, frequency_lines, simulate_test
from automodal.errors import InputError
from automodal.frfdata import FRFData
from automodal.io import report as report_module
from automodal.io.frf_file import write_frf
from automodal.io.report import format_table, read_report, report_dict, write_report
from automodal.pipeline import identify
from automodal.result import PoleTable, Result
from automodal.settings import Settings

FIXED_TIME = "2026-01-02T03:04:05Z"

# ---------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def identified() -> tuple[Result, FRFData]:
    """A real run on a 4-DOF chain: three or four physical modes among spurious ones."""
    data, _ = simulate_test(
        damp(chain(4), zeta=0.01),
        outputs=[0, 1, 2, 3],
        inputs=[3],
        frequency_hz=frequency_lines(40.0, 400),
        noise=0.01,
        seed=1,
    )
    return identify(data, Settings(n_bootstrap=20, seed=1, jobs=1)), data


@pytest.fixture
def result(identified) -> Result:
    return identified[0]


@pytest.fixture
def data(identified) -> FRFData:
    return identified[1]


@pytest.fixture
def fixed_clock(monkeypatch) -> None:
    """Make ``created`` the same in every report of a test."""
    monkeypatch.setattr(report_module, "utc_now", lambda: FIXED_TIME)


def with_modes(result: Result, modes: list) -> Result:
    """A copy of ``result`` with other modes (the module's result is never changed)."""
    return dataclasses.replace(result, modes=modes)


def changed_mode(result: Result, index: int, **changes) -> Result:
    """A copy of ``result`` whose mode ``index`` has some fields changed."""
    modes = list(result.modes)
    modes[index] = dataclasses.replace(modes[index], **changes)
    return with_modes(result, modes)


def folder_names(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


# ----------------------------------------------------------------------------- content


def test_the_run_gives_something_to_report(result):
    assert result.modes and any(m.physical for m in result.modes)
    assert not all(m.physical for m in result.modes)


def test_report_dict_follows_the_schema(result, data):
    report = report_dict(result, data)
    validate_report(report)
    assert_plain_json_types(report)
    assert_no_non_finite_text(json.dumps(report))


def test_modes_carry_every_field_of_the_result(result, data):
    report = report_dict(result, data)
    assert len(report["modes"]) == len(result.modes)
    for entry, mode in zip(report["modes"], result.modes):
        assert entry["id"] == mode.id
        assert entry["frequency_hz"] == mode.frequency_hz
        assert entry["frequency_ci95_hz"] == list(mode.frequency_ci95_hz)
        assert entry["damping_ci95"] == list(mode.damping_ci95)
        assert entry["physicalness"] == mode.physicalness
        assert entry["physical"] is mode.physical
        assert entry["n_members"] == mode.n_members
        shape = np.array(entry["mode_shape"]["real"]) + 1j * np.array(entry["mode_shape"]["imag"])
        np.testing.assert_allclose(shape, mode.mode_shape, rtol=0, atol=1e-15)
        np.testing.assert_allclose(entry["mode_shape_std"], mode.mode_shape_std, atol=1e-15)
        assert entry["cluster"] == mode.cluster
        assert entry["cluster_dim"] == mode.cluster_dim
        assert entry["features"] == mode.features


def test_input_settings_trashbox_and_summary(result, data):
    report = report_dict(result, data)
    inp = report["input"]
    assert inp["path"] is None and inp["sha256"] is None
    assert (inp["n_freq"], inp["n_outputs"], inp["n_inputs"]) == (400, 4, 1)
    assert inp["band_hz"] == list(result.band_hz)
    assert inp["quantity"] == "displacement"
    assert inp["output_names"] == data.output_names
    assert inp["input_names"] == data.input_names
    assert inp["attributes"] == data.attributes
    settings = report["settings"]
    assert settings["seed"] == 1 and settings["n_bootstrap"] == 20
    assert "jobs" not in settings
    assert settings["orders"] == result.orders
    assert report["trashbox"] == {"n_members": result.trashbox_members}
    summary = report["summary"]
    assert summary["n_physical"] == len(result.physical_modes)
    assert summary["n_clusters"] == len(result.modes)
    assert summary["n_bootstrap"] == 20
    assert summary["runtime_s"] == result.runtime_s
    assert report["warnings"] == result.warnings
    assert report["automodal_version"] == result.automodal_version


def test_created_is_now_in_utc(result, data):
    from datetime import datetime, timezone

    report = report_dict(result, data)
    created = datetime.strptime(report["created"], "%Y-%m-%dT%H:%M:%SZ")
    now = datetime.now(timezone.utc).replace(tzinfo=None)
    assert abs((now - created).total_seconds()) < 60


def test_input_file_is_named_and_hashed(result, data, tmp_path):
    path = tmp_path / "test.h5"
    write_frf(path, data)
    expected = hashlib.sha256(path.read_bytes()).hexdigest()
    report = report_dict(result, data, input_path=str(path))
    assert report["input"]["path"] == str(path)
    assert report["input"]["sha256"] == expected
    from_source = report_dict(result, dataclasses.replace(data, source=str(path)))
    assert from_source["input"]["sha256"] == expected
    assert report["warnings"] == result.warnings


def test_large_input_file_is_hashed_in_chunks(result, data, tmp_path):
    path = tmp_path / "big.bin"
    content = np.random.default_rng(0).bytes(3 * (1 << 20) + 12345)
    path.write_bytes(content)
    report = report_dict(result, data, input_path=path)
    assert report["input"]["sha256"] == hashlib.sha256(content).hexdigest()
    assert report["input"]["path"] == str(path)


def test_unreadable_input_file_gives_null_sha256_and_a_warning(result, data, tmp_path):
    missing = tmp_path / "gone.h5"
    report = report_dict(result, data, input_path=str(missing))
    assert report["input"]["sha256"] is None
    assert any("gone.h5" in w and "sha256" in w for w in report["warnings"])
    validate_report(report)


def test_modes_are_sorted_by_frequency(result, data):
    shuffled = with_modes(result, list(reversed(result.modes)))
    report = report_dict(shuffled, data)
    freqs = [m["frequency_hz"] for m in report["modes"]]
    assert freqs == sorted(freqs)
    assert [m["id"] for m in report["modes"]] == [m.id for m in result.modes]


def test_mode_shape_is_scaled_to_a_largest_entry_of_one(result, data):
    mode = result.modes[0]
    factor = 2.0 - 3.0j
    skewed = changed_mode(
        result, 0, mode_shape=mode.mode_shape * factor, mode_shape_std=mode.mode_shape_std * 5
    )
    entry = report_dict(skewed, data)["modes"][0]
    shape = np.array(entry["mode_shape"]["real"]) + 1j * np.array(entry["mode_shape"]["imag"])
    k = int(np.argmax(np.abs(shape)))
    assert shape[k] == 1 + 0j
    np.testing.assert_allclose(shape, mode.mode_shape, atol=1e-12)
    np.testing.assert_allclose(
        entry["mode_shape_std"], mode.mode_shape_std * 5 / abs(factor), rtol=1e-12
    )


def test_numpy_scalars_and_odd_attributes_become_plain_json(result, data):
    mode = result.modes[0]
    numpyish = changed_mode(
        result,
        0,
        id=np.int64(mode.id),
        frequency_hz=np.float64(mode.frequency_hz),
        damping_ratio=np.float32(mode.damping_ratio),
        physical=np.bool_(mode.physical),
        n_members=np.int32(mode.n_members),
        frequency_ci95_hz=np.array(mode.frequency_ci95_hz),
    )
    numpyish = dataclasses.replace(
        numpyish, trashbox_members=np.int64(7), runtime_s=np.float64(1.5)
    )
    odd = dataclasses.replace(
        data,
        attributes={
            "temperature": np.float32(21.5),
            "count": np.int16(3),
            "ok": np.bool_(True),
            "levels": np.array([1.0, 2.0]),
            "raw": b"bytes",
            "nested": {"a": (1, 2), "b": [np.int64(4)]},
            "name": np.str_("beam"),
        },
    )
    report = report_dict(numpyish, odd)
    assert_plain_json_types(report)
    assert report["input"]["attributes"] == {
        "temperature": 21.5,
        "count": 3,
        "ok": True,
        "levels": [1.0, 2.0],
        "raw": "bytes",
        "nested": {"a": [1, 2], "b": [4]},
        "name": "beam",
    }
    assert report["trashbox"]["n_members"] == 7
    validate_report(report)


# ------------------------------------------------------------------------- non-finite


def test_nan_in_a_mode_becomes_null_with_a_warning(result, data, tmp_path):
    mode = result.modes[1]
    shape = mode.mode_shape.copy()
    small = int(np.argmin(np.abs(shape)))
    shape[small] = complex(np.nan, 0.0)
    broken = changed_mode(
        result,
        1,
        frequency_std_hz=float("nan"),
        damping_ci95=(float("-inf"), mode.damping_ci95[1]),
        mode_shape=shape,
    )
    report = report_dict(broken, data)
    entry = report["modes"][1]
    assert entry["frequency_std_hz"] is None
    assert entry["damping_ci95"][0] is None and entry["damping_ci95"][1] is not None
    assert entry["mode_shape"]["real"][small] is None
    assert entry["mode_shape"]["imag"][small] == 0.0
    new = report["warnings"][len(result.warnings):]
    assert len(new) == 3
    for field in ("modes[1].frequency_std_hz", "modes[1].damping_ci95",
                  "modes[1].mode_shape.real"):
        assert any(field in w and "null" in w for w in new), field
    validate_report(report, nullable=True)
    text = json.dumps(report, allow_nan=False)
    assert_no_non_finite_text(text)
    for name in ("r.json", "r.h5"):
        write_report(tmp_path / name, broken, data)
        assert read_report(tmp_path / name)["modes"][1]["frequency_std_hz"] is None
    with h5py.File(tmp_path / "r.h5") as f:
        assert np.isnan(f["modes/frequency_std_hz"][1])


def test_nan_outside_the_modes_is_named_too(result, data):
    orders = dict(result.orders, misfit=[*result.orders["misfit"][:-1], float("inf")])
    broken = dataclasses.replace(result, orders=orders, runtime_s=float("nan"))
    report = report_dict(broken, dataclasses.replace(data, attributes={"t": float("nan")}))
    assert report["settings"]["orders"]["misfit"][-1] is None
    assert report["summary"]["runtime_s"] is None
    assert report["input"]["attributes"]["t"] is None
    new = " | ".join(report["warnings"])
    for field in ("settings.orders.misfit", "summary.runtime_s", "input.attributes.t"):
        assert field in new
    assert_no_non_finite_text(json.dumps(report, allow_nan=False))


# -------------------------------------------------------------------------- the files


def test_json_report_is_indented_and_follows_the_schema(result, data, tmp_path):
    path = tmp_path / "report.json"
    write_report(path, result, data)
    text = path.read_text(encoding="utf-8")
    assert text.startswith('{\n  "format": "automodal-report",\n')
    assert_no_non_finite_text(text)
    validate_report(json.loads(text))
    validate_report(read_report(path))
    assert folder_names(tmp_path) == ["report.json"]


@pytest.mark.parametrize("name", ["report.json", "report.h5", "report.hdf5", "REPORT.JSON"])
def test_round_trip_gives_back_report_dict(result, data, tmp_path, fixed_clock, name):
    path = tmp_path / name
    write_report(path, result, data)
    assert read_report(path) == report_dict(result, data)
    assert read_report(str(path)) == report_dict(result, data)


def test_hdf5_report_follows_the_schema(result, data, tmp_path):
    path = tmp_path / "report.h5"
    write_report(path, result, data)
    report = read_report(path)
    validate_report(report)
    assert_plain_json_types(report)
    assert folder_names(tmp_path) == ["report.h5"]


def test_hdf5_layout(result, data, tmp_path, fixed_clock):
    path = tmp_path / "report.h5"
    write_report(path, result, data)
    report = report_dict(result, data)
    n, ny = len(report["modes"]), data.n_outputs
    with h5py.File(path, "r") as f:
        assert f.attrs["format"] == "automodal-report"
        assert int(f.attrs["version"]) == 1
        assert f.attrs["automodal_version"] == result.automodal_version
        assert f.attrs["created"] == FIXED_TIME
        assert json.loads(f.attrs["settings"]) == report["settings"]
        assert json.loads(f.attrs["report_json"]) == report
        assert [str(w) for w in f.attrs["warnings"]] == report["warnings"]

        modes = f["modes"]
        expected = {
            "frequency_hz": ((n,), "f"),
            "frequency_std_hz": ((n,), "f"),
            "frequency_ci95_hz": ((n, 2), "f"),
            "damping_ratio": ((n,), "f"),
            "damping_std": ((n,), "f"),
            "damping_ci95": ((n, 2), "f"),
            "physicalness": ((n,), "f"),
            "physical": ((n,), "b"),
            "n_members": ((n,), "i"),
            "mode_shape": ((n, ny), "c"),
            "mode_shape_std": ((n, ny), "f"),
            "mpc": ((n,), "f"),
            "id": ((n,), "i"),
            "cluster": ((n,), "i"),
        }
        for name, (shape, kind) in expected.items():
            assert modes[name].shape == shape, name
            assert modes[name].dtype.kind == kind, name
        entries = report["modes"]
        for name in ("frequency_hz", "damping_ci95", "physical", "n_members", "mode_shape_std"):
            np.testing.assert_array_equal(modes[name][()], [m[name] for m in entries], name)
        shapes = np.array(
            [np.array(m["mode_shape"]["real"]) + 1j * np.array(m["mode_shape"]["imag"])
             for m in entries]
        )
        np.testing.assert_array_equal(modes["mode_shape"][()], shapes)
        for name in result.modes[0].features:
            assert modes[f"features/{name}"].shape == (n,)

        inp = f["input"].attrs
        assert inp["n_freq"] == data.n_freq and inp["n_outputs"] == ny and inp["n_inputs"] == 1
        assert inp["quantity"] == data.quantity
        np.testing.assert_array_equal(inp["band_hz"], result.band_hz)
        assert [str(s) for s in inp["output_names"]] == data.output_names
        assert [str(s) for s in inp["input_names"]] == data.input_names
        assert json.loads(inp["attributes"]) == report["input"]["attributes"]
        assert "path" not in inp and "sha256" not in inp

        poles = f["poles"]
        for name, kind in (("frequency_hz", "f"), ("damping_ratio", "f"), ("cluster", "i"),
                           ("replicate", "i")):
            assert poles[name].shape == result.poles.frequency_hz.shape, name
            assert poles[name].dtype.kind == kind, name
        np.testing.assert_array_equal(poles["cluster"][()], result.poles.cluster)
        np.testing.assert_array_equal(poles["replicate"][()], result.poles.replicate)
        np.testing.assert_array_equal(poles["frequency_hz"][()], result.poles.frequency_hz)
        assert np.sum(poles["cluster"][()] == -1) == result.trashbox_members
        assert f["trashbox"].attrs["n_members"] == result.trashbox_members
        assert f["summary"].attrs["n_physical"] == report["summary"]["n_physical"]


def test_hdf5_input_group_names_the_file(result, data, tmp_path):
    source = tmp_path / "test.h5"
    write_frf(source, data)
    path = tmp_path / "report.h5"
    write_report(path, result, data, input_path=str(source))
    with h5py.File(path, "r") as f:
        assert f["input"].attrs["path"] == str(source)
        assert f["input"].attrs["sha256"] == hashlib.sha256(source.read_bytes()).hexdigest()


def test_a_run_without_modes_writes_valid_reports(result, data, tmp_path):
    empty = dataclasses.replace(
        result,
        modes=[],
        trashbox_members=0,
        poles=PoleTable(np.zeros(0), np.zeros(0), np.zeros(0, int), np.zeros(0, int)),
    )
    for name in ("empty.json", "empty.h5"):
        write_report(tmp_path / name, empty, data)
        report = read_report(tmp_path / name)
        validate_report(report)
        assert report["modes"] == [] and report["summary"]["n_physical"] == 0
    with h5py.File(tmp_path / "empty.h5", "r") as f:
        assert f["modes/mode_shape"].shape == (0, data.n_outputs)
        assert f["modes/frequency_ci95_hz"].shape == (0, 2)
        assert f["poles/cluster"].shape == (0,)


# ------------------------------------------------------------------- refusals, failures


@pytest.mark.parametrize("name", ["report.txt", "report", "report.csv", "report.json.bak"])
def test_unknown_suffix_is_refused_before_writing(result, data, tmp_path, name):
    with pytest.raises(InputError, match="suffix") as info:
        write_report(tmp_path / name, result, data)
    assert name in str(info.value)
    assert folder_names(tmp_path) == []


def _failing_json_dump(obj, fh, **kwargs):
    fh.write('{"format": "automodal-report", "modes": [')
    raise OSError(28, "No space left on device")


def test_failure_while_writing_json_leaves_no_file(result, data, tmp_path, monkeypatch):
    monkeypatch.setattr(json, "dump", _failing_json_dump)
    with pytest.raises(OSError, match="No space"):
        write_report(tmp_path / "report.json", result, data)
    assert folder_names(tmp_path) == []


def test_failure_while_writing_keeps_the_old_report(result, data, tmp_path, monkeypatch):
    path = tmp_path / "report.json"
    path.write_text("old")
    monkeypatch.setattr(json, "dump", _failing_json_dump)
    with pytest.raises(OSError):
        write_report(path, result, data)
    assert path.read_text() == "old"
    assert folder_names(tmp_path) == ["report.json"]


def test_failure_while_writing_hdf5_leaves_no_file(result, data, tmp_path, monkeypatch):
    calls = []
    real = h5py.Group.create_dataset

    def failing(self, name, *args, **kwargs):
        calls.append(name)
        if len(calls) > 3:
            raise RuntimeError("disk went away")
        return real(self, name, *args, **kwargs)

    monkeypatch.setattr(h5py.Group, "create_dataset", failing)
    with pytest.raises(RuntimeError, match="disk went away"):
        write_report(tmp_path / "report.h5", result, data)
    assert len(calls) == 4
    assert folder_names(tmp_path) == []


def test_nan_in_a_hand_made_report_is_refused_without_a_file(tmp_path):
    bad = {"format": "automodal-report", "version": 1, "x": float("nan")}
    with pytest.raises(ValueError):
        report_module.save_report(tmp_path / "r.json", bad)
    assert folder_names(tmp_path) == []


# ------------------------------------------------------------------------------ reading


def test_read_report_finds_the_format_by_content_for_other_suffixes(result, data, tmp_path):
    write_report(tmp_path / "r.h5", result, data)
    write_report(tmp_path / "r.json", result, data)
    shutil.copy(tmp_path / "r.h5", tmp_path / "r.dat")
    shutil.copy(tmp_path / "r.json", tmp_path / "r.txt")
    assert read_report(tmp_path / "r.dat") == read_report(tmp_path / "r.h5")
    assert read_report(tmp_path / "r.txt") == read_report(tmp_path / "r.json")


def _bad_report_files(folder: Path, good_h5: Path) -> dict[str, Path]:
    files = {}
    files["missing"] = folder / "missing.json"
    files["folder"] = folder / "folder.json"
    files["folder"].mkdir()
    files["not json"] = folder / "garbage.json"
    files["not json"].write_text("{not json")
    files["binary"] = folder / "binary.json"
    files["binary"].write_bytes(b"\xff\xfe\x00\x81")
    files["other json"] = folder / "other.json"
    files["other json"].write_text(json.dumps({"format": "something-else", "version": 1}))
    files["list"] = folder / "list.json"
    files["list"].write_text("[1, 2]")
    files["newer"] = folder / "newer.json"
    files["newer"].write_text(json.dumps({"format": "automodal-report", "version": 2,
                                          "modes": []}))
    files["no modes"] = folder / "nomodes.json"
    files["no modes"].write_text(json.dumps({"format": "automodal-report", "version": 1}))
    files["not hdf5"] = folder / "text.h5"
    files["not hdf5"].write_text("hello")
    files["truncated"] = folder / "truncated.h5"
    files["truncated"].write_bytes(good_h5.read_bytes()[:2000])
    files["frf file"] = folder / "frf.h5"
    with h5py.File(files["frf file"], "w") as f:
        f.attrs["format"] = "automodal-frf"
    return files


def test_bad_report_files_are_refused_naming_the_file(result, data, tmp_path):
    good = tmp_path / "good.h5"
    write_report(good, result, data)
    for label, path in _bad_report_files(tmp_path, good).items():
        with pytest.raises(InputError) as info:
            read_report(path)
        assert str(path) in str(info.value), label
        assert info.value.path == str(path), label
        assert "\n" not in str(info.value), label


def test_newer_version_is_named_in_the_message(tmp_path):
    path = tmp_path / "newer.json"
    path.write_text(json.dumps({"format": "automodal-report", "version": 2, "modes": []}))
    with pytest.raises(InputError, match="version 2 is newer"):
        read_report(path)


# -------------------------------------------------------------------------------- table


def test_table_lists_the_physical_modes_numbered_from_one(result):
    lines = format_table(result).splitlines()
    header, rule, rows, summary = lines[0], lines[1], lines[2:-1], lines[-1]
    for word in ("mode", "frequency (Hz)", "damping (%)", "physicalness", "members", "MPC"):
        assert word in header
    assert "class" not in header
    assert set(rule.replace(" ", "")) == {"-"}
    physical = sorted(result.physical_modes, key=lambda m: m.frequency_hz)
    assert 0 < len(physical) < len(result.modes)  # the test needs both kinds
    assert len(rows) == len(physical)
    for k, (row, mode) in enumerate(zip(rows, physical), start=1):
        cells = row.split()
        assert cells[0] == str(k) == str(mode.mode_number)
        assert cells[1] == f"{mode.frequency_hz:.4f}"
        assert cells[-2] == str(mode.n_members)
    n_other = len(result.modes) - len(physical)
    assert summary.startswith(f"{len(physical)} physical modes; {n_other} other clusters not "
                              "shown (--all)")
    assert f"{result.trashbox_members} poles in the Trashbox" in summary
    assert f"runtime {result.runtime_s:.1f} s" in summary


def test_table_with_all_lists_every_cluster_marked(result):
    lines = format_table(result, show_all=True).splitlines()
    rows = lines[2:-1]
    assert "class" in lines[0] and len(rows) == len(result.modes)
    for row, mode in zip(rows, sorted(result.modes, key=lambda m: m.frequency_hz)):
        cells = row.split()
        assert cells[0] == (str(mode.mode_number) if mode.physical else "-")
        assert ("not physical" in row) is (not mode.physical)
    assert "other clusters not physical" in lines[-1]


def test_table_spread_of_a_single_member_is_not_zero(result):
    lonely = dataclasses.replace(result.modes[0], n_members=1, frequency_std_hz=0.0,
                                 damping_std=0.0, estimator="bootstrap", physical=True,
                                 mode_number=1)
    row = format_table(with_modes(result, [lonely])).splitlines()[2]
    assert "± 0.0000" not in row and "± 0.000" not in row
    assert row.count("n/a") == 2


@pytest.mark.parametrize("show_all", [False, True])
def test_table_columns_are_aligned(result, show_all):
    lines = format_table(result, show_all=show_all).splitlines()[:-1]
    assert len({len(line) for line in lines}) == 1
    ends = {line.index("±") for line in lines[2:]}
    assert len(ends) == 1


def test_table_of_a_run_without_modes(result):
    text = format_table(with_modes(result, []))
    assert "no mode" in text
    assert text.splitlines()[-1].startswith("0 physical modes;")


# -------------------------------------------------------------------------------- mode numbers


def test_physical_modes_are_numbered_from_one_by_frequency(result, data):
    physical = sorted(result.physical_modes, key=lambda m: m.frequency_hz)
    assert [m.mode_number for m in physical] == list(range(1, len(physical) + 1))
    assert all(m.mode_number is None for m in result.modes if not m.physical)
    content = report_dict(result, data)
    assert [m["mode_number"] for m in content["modes"] if m["physical"]] == [
        m.mode_number for m in physical]
    validate_report(content)


def test_a_report_without_mode_numbers_is_numbered_when_read(result, data):
    from automodal.report_model import Report

    content = report_dict(result, data)
    for m in content["modes"]:
        del m["mode_number"]
    old = Report.from_dict(content)
    assert [m.mode_number for m in old.modes] == [
        m["mode_number"] for m in report_dict(result, data)["modes"]]
    assert list(old.mode_table().numbers) == [m.mode_number or 0 for m in old.modes]


def test_a_test_date_that_is_no_date_is_warned_of():
    """An input whose test_date reads as no date: track and monitoring place its report at
    the time it was made, which they did silently; the report now says so."""
    from automodal.io.report import date_warnings

    assert date_warnings({}) == []
    assert date_warnings({"test_date": "2026-03-04T05:06:07"}) == []
    assert date_warnings({"date": "2026-03-04", "test_date": "soon"}) == []  # one reads
    (warning,) = date_warnings({"test_date": "not a date"})
    assert "'not a date' is not an ISO 8601 date" in warning and "time it was made" in warning
    assert len(date_warnings({"timestamp": 12345})) == 1
