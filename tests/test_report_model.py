"""The typed report model, the one JSON-safe conversion, the report's JSON Schema, ``jobs``."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from report_schema import schema_errors, validate_report

from automodal.app.batch import run_batch
from automodal.app.run import check_jobs
from automodal.cli import main
from automodal.core.matching import match
from automodal.core.simulate import chain, damp, frequency_lines, simulate_test
from automodal.errors import InputError
from automodal.frfdata import FRFData
from automodal.io import report as report_module
from automodal.io.frf_file import write_frf
from automodal.io.json_safe import (
    json_safe,
    json_safe_with_warnings,
    non_finite_warnings,
)
from automodal.io.report import (
    build_report,
    load_report,
    read_report,
    report_dict,
    save_report,
    write_report,
)
from automodal.pipeline import identify
from automodal.report_model import Report
from automodal.result import Result
from automodal.settings import Settings

FIXED_TIME = "2026-01-02T03:04:05Z"


@pytest.fixture(scope="module")
def identified(tmp_path_factory) -> tuple[Result, FRFData, Path]:
    """A real run on a 4-DOF chain read from a file (so that the input is hashed)."""
    data, _ = simulate_test(damp(chain(4), zeta=0.01), outputs=[0, 1, 2, 3], inputs=[3],
                            frequency_hz=frequency_lines(40.0, 400), noise=0.01, seed=1)
    data.attributes["test_date"] = "2026-03-04T05:06:07"
    path = tmp_path_factory.mktemp("input") / "chain4.h5"
    write_frf(path, data)
    return identify(data, Settings(n_bootstrap=20, seed=1, jobs=1)), data, path


@pytest.fixture
def fixed_clock(monkeypatch) -> None:
    monkeypatch.setattr(report_module, "utc_now", lambda: FIXED_TIME)


@pytest.fixture
def report(identified, fixed_clock) -> Report:
    result, data, path = identified
    return build_report(result, data, path)


def cli(*args):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


# ------------------------------------------------------------------------------ round trip


def test_result_to_dict_to_model_is_the_same_report(identified, report):
    result, data, path = identified
    content = report.to_dict()
    assert content == report_dict(result, data, path)  # the one builder
    back = Report.from_dict(content)
    assert back == report
    assert back.to_dict() == content
    assert list(back.to_dict()) == list(content)  # keys in the written order
    assert list(back.to_dict()["input"]) == list(content["input"])
    assert Report.from_dict(json.loads(json.dumps(content))) == report


def test_model_of_json_and_hdf5_files_equals_the_written_report(report, identified, tmp_path):
    result = identified[0]
    for name in ("r.json", "r.h5"):
        save_report(tmp_path / name, report, result.poles, frf=result.frf_fit)
        assert load_report(tmp_path / name) == report
        assert read_report(tmp_path / name) == report.to_dict()
    loaded = load_report(tmp_path / "r.h5", arrays=True)
    assert loaded.arrays.poles["frequency_hz"].size == result.poles.frequency_hz.size
    assert loaded.arrays.frf["measured"].ndim == 3
    assert load_report(tmp_path / "r.json", arrays=True).arrays.poles is None


def test_a_dict_and_the_model_write_the_same_file(report, tmp_path):
    save_report(tmp_path / "model.json", report)
    save_report(tmp_path / "dict.json", report.to_dict())
    assert (tmp_path / "model.json").read_text() == (tmp_path / "dict.json").read_text()


def test_extra_keys_of_a_later_writer_are_kept_in_place(report):
    content = report.to_dict()
    content["later"] = {"x": 1}
    content["input"]["new_field"] = [1, 2]
    content["modes"][0]["new_mode_field"] = "yes"
    content["summary"]["n_something"] = 3
    back = Report.from_dict(copy.deepcopy(content))
    assert back.to_dict() == content
    assert back.extra == {"later": {"x": 1}} and back.modes[0].extra == {"new_mode_field": "yes"}


def test_a_report_without_the_later_additions_is_read(report):
    content = report.to_dict()
    for key in ("frequency_range_hz", "n_lines_analysed", "reciprocity", "mode_shape_channels"):
        del content["input"][key]
    for mode in content["modes"]:
        for key in ("cluster", "cluster_dim", "features"):
            del mode[key]
    del content["summary"]["n_reference_clusters"]
    back = Report.from_dict(copy.deepcopy(content))
    assert back.to_dict() == content
    assert back.shape_channels == content["input"]["output_names"]
    table = back.mode_table()
    assert len(set(table.cluster.tolist())) == len(content["modes"])  # each mode its own


# ------------------------------------------------------------------------------ written once


def test_derived_values(report, identified):
    result, data, _ = identified
    assert report.shape_channels == list(result.shape_channels or data.output_names)
    report.input.mode_shape_channels = None
    assert report.shape_channels == data.output_names
    assert report.shape_output_indices() == list(range(data.n_outputs))
    report.input.mode_shape_channels = ["dof1", "dof3"]
    assert report.shape_output_indices() == [0, 2]
    physical = report.physical_modes
    assert [m.id for m in physical] == [m.id for m in sorted(result.physical_modes,
                                                              key=lambda m: m.frequency_hz)]
    assert report.n_physical == len(result.physical_modes) == report.summary.n_physical
    assert report.test_time() == ("2026-03-04T05:06:07Z", "test_date")
    assert report.test_date() == "2026-03-04T05:06:07Z"
    assert report.band_hz == tuple(result.band_hz)
    mode = report.modes[0]
    np.testing.assert_allclose(mode.shape.real, mode.shape_real)
    table = report.mode_table()
    assert table.n_modes == len(report.modes)
    assert table.shapes.shape == (len(report.modes), len(mode.shape_real))


# ------------------------------------------------------------------------------ refusals


def _malformed(content: dict) -> dict[str, dict]:
    cases = {}

    def case(field: str, change) -> None:
        bad = copy.deepcopy(content)
        change(bad)
        cases[field] = bad

    case("modes[1].frequency_hz", lambda r: r["modes"][1].update(frequency_hz="fast"))
    case("modes[0].mode_shape.imag", lambda r: r["modes"][0]["mode_shape"]["imag"].pop())
    case("modes[0].physical", lambda r: r["modes"][0].update(physical=1))
    case("modes[2].n_members", lambda r: r["modes"][2].pop("n_members"))
    case("input.n_outputs", lambda r: r["input"].update(n_outputs="4"))
    case("input.band_hz", lambda r: r["input"].update(band_hz=[1.0]))
    case("input", lambda r: r.pop("input"))
    case("summary.runtime_s", lambda r: r["summary"].update(runtime_s=math.inf))
    case("trashbox.n_members", lambda r: r["trashbox"].update(n_members=-1))
    case("warnings[0]", lambda r: r.update(warnings=[3]))
    case("modes", lambda r: r.update(modes={}))
    case("created", lambda r: r.pop("created"))
    k = next(i for i, m in enumerate(content["modes"]) if m["physical"])

    def shorter_shape(r: dict) -> None:  # both parts cut: one value fewer than channels
        r["modes"][k]["mode_shape"]["real"].pop()
        r["modes"][k]["mode_shape"]["imag"].pop()
    case(f"modes[{k}].mode_shape", shorter_shape)
    return cases


def test_malformed_reports_are_refused_naming_the_field(report):
    for field, bad in _malformed(report.to_dict()).items():
        with pytest.raises(InputError) as info:
            Report.from_dict(bad)
        assert f"field {field} " in str(info.value), field
        assert "\n" not in str(info.value)


NOT_IN_SCHEMA = ("modes[0].mode_shape.imag", "summary.runtime_s", ".mode_shape")
"""Malformations a JSON Schema cannot express (lengths that must agree, a Python inf):
``validate_report`` checks them beside the schema (a field ending in an entry here)."""


def test_the_schema_refuses_them_too_naming_the_field(report):
    for field, bad in _malformed(report.to_dict()).items():
        if field in NOT_IN_SCHEMA or field.endswith(NOT_IN_SCHEMA[-1]):
            with pytest.raises(AssertionError, match=field.split(".")[0].split("[")[0]):
                validate_report(bad)
            continue
        errors = schema_errors(bad)
        assert errors, field
        top = field.split(".")[0].split("[")[0]
        assert any(top in e for e in errors), (field, errors)


def test_other_formats_and_versions_are_refused(report):
    content = report.to_dict()
    with pytest.raises(InputError, match="not an automodal report"):
        Report.from_dict({**content, "format": "other"})
    with pytest.raises(InputError, match="version 2 is newer"):
        Report.from_dict({**content, "version": 2})
    with pytest.raises(InputError, match="not an automodal report"):
        Report.from_dict([content])


def test_malformed_report_file_exits_2_in_plot_and_track(report, tmp_path):
    bad = report.to_dict()
    bad["modes"][1]["damping_ratio"] = "low"
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(bad))
    for args in (("plot", path), ("track", path, "-o", tmp_path / "h.h5")):
        run = cli(*args)
        assert run.exit_code == 2, run.output
        lines = run.stderr.splitlines()
        assert len(lines) == 1 and str(path) in lines[0]
        assert "modes[1].damping_ratio" in lines[0]
    assert not (tmp_path / "bad.png").exists() and not (tmp_path / "h.h5").exists()


def test_malformed_baseline_exits_2_in_identify(report, identified, tmp_path):
    bad = report.to_dict()
    del bad["summary"]
    path = tmp_path / "base.json"
    path.write_text(json.dumps(bad))
    run = cli("identify", identified[2], "--baseline", path, "--bootstrap", "4")
    assert run.exit_code == 2 and "field summary is missing" in run.stderr


# ------------------------------------------------------------------------------ the schema


def test_reports_of_the_suite_follow_the_schema(identified, tmp_path):
    result, data, path = identified
    for name in ("r.json", "r.h5"):
        write_report(tmp_path / name, result, data, path)
        content = read_report(tmp_path / name)
        assert schema_errors(content) == []
        validate_report(content)


def test_a_report_with_nulls_and_a_monitoring_block_follows_the_schema(identified, tmp_path):
    result, data, path = identified
    base = tmp_path / "base.json"
    write_report(base, result, data, path)
    out = tmp_path / "again.h5"
    run = cli("identify", path, "-o", out, "--baseline", base, "-q", "--bootstrap", "20",
              "--seed", "1", "--jobs", "1")
    assert run.exit_code in (0, 3), run.output
    content = read_report(out)
    assert "monitoring" in content
    assert schema_errors(content) == []
    content["monitoring"]["modes"][0]["status"] = "fine"
    assert any("monitoring" in e for e in schema_errors(content))
    nulls = copy.deepcopy(read_report(base))
    nulls["modes"][0]["frequency_hz"] = None
    nulls["modes"][0]["mode_shape"]["real"][0] = None
    assert schema_errors(nulls) == []
    validate_report(nulls, nullable=True)


def test_the_schema_is_package_data():
    from automodal.schemas import REPORT_V1

    schema = json.loads(REPORT_V1.read_text())
    assert schema["properties"]["format"] == {"const": "automodal-report"}
    text = Path(__file__).parents[1].joinpath("pyproject.toml").read_text()
    assert 'automodal = ["schemas/*.json"]' in text


# ------------------------------------------------------------------------------ JSON-safe


def test_json_safe_converts_numpy_and_names_non_finite_fields():
    value = {"a": np.float32(1.5), "b": [np.int64(2), np.nan, np.inf], "c": np.bool_(True),
             "d": np.array([[1.0, 2.0]]), "e": 1 + 2j, "f": Path("x/y"), "g": b"t",
             "h": (np.float64(-np.inf),)}
    found: list[str] = []
    clean = json_safe(value, "top", found)
    assert clean == {"a": 1.5, "b": [2, None, None], "c": True, "d": [[1.0, 2.0]],
                     "e": {"real": 1.0, "imag": 2.0}, "f": "x/y", "g": "t", "h": [None]}
    assert type(clean["b"][0]) is int and type(clean["a"]) is float
    assert found == ["top.b[1]", "top.b[2]", "top.h[0]"]
    assert non_finite_warnings(found) == [
        "report field top.b: 2 value(s) not finite, written as null",
        "report field top.h: 1 value(s) not finite, written as null",
    ]
    _, warnings = json_safe_with_warnings({"x": float("nan")}, what="summary")
    assert warnings == ["summary field x: 1 value(s) not finite, written as null"]


# ------------------------------------------------------------------------------ jobs and matching


def test_jobs_is_none_or_at_least_one_everywhere(identified, tmp_path):
    assert check_jobs(None) is None and check_jobs(3) == 3
    for bad in (0, -1, 1.5, True):
        with pytest.raises(InputError, match="jobs"):
            check_jobs(bad)
    with pytest.raises(InputError, match="jobs"):
        run_batch([identified[2]], tmp_path / "out", Settings(n_bootstrap=4), jobs=0)
    run = cli("identify", identified[2], "--jobs", "0")
    assert run.exit_code == 2 and "--jobs" in run.stderr
    help_text = cli("identify", "--help").output
    assert "automatic" in help_text and "x>=1" in help_text


def test_match_is_a_pure_array_function():
    macs = np.array([[1.0, 0.2], [0.2, 1.0]])
    pairs = match(np.array([5.0, 12.0]), np.array([12.1, 5.01])[::-1], macs,
                  frequency_weight=0.05, max_relative_shift=0.15, min_mac=0.5)
    assert pairs == [(0, 0), (1, 1)]
    assert match(np.array([5.0]), np.array([9.0]), np.full((1, 1), np.nan),
                 frequency_weight=0.05, max_relative_shift=0.15, min_mac=0.5) == []


def test_a_run_with_the_noise_model_reports_it(identified, tmp_path):
    _, data, path = identified
    result = identify(data, Settings(n_bootstrap=20, seed=1, jobs=1, weighting="noise"))
    assert result.noise is not None
    for name in ("n.json", "n.h5"):
        write_report(tmp_path / name, result, data, path)
        content = read_report(tmp_path / name)
        assert schema_errors(content) == []
        noise = content["noise"]
        assert noise["source"] == "data"
        assert set(noise["output_level"]) == set(data.output_names)
        assert all(0 < v < 0.1 for v in noise["output_level"].values())  # 1 % noise
        assert Report.from_dict(content).noise.source == "data"
    bad = copy.deepcopy(content)
    bad["noise"]["source"] = "guess"
    assert any("noise" in e for e in schema_errors(bad))
    plain = read_report(tmp_path / "n.json")
    plain.pop("noise")
    assert Report.from_dict(plain).noise is None
