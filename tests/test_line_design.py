"""``automodal design``: the designed lines' properties, the command's refusals, and the
identification on lines that are not equidistant."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from automodal.cli import main
from automodal.core import simulate as sim
from automodal.core import subspace
from automodal.core.line_design import (
    RULES,
    design_lines,
    half_power_counts,
    mapped_angle,
)
from automodal.core.summary import local_spacing

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data"

CHAIN6_F = np.array([3.8368, 11.2874, 18.0821, 23.8258, 28.1849, 30.9060])
CHAIN6_Z = np.array([0.010, 0.0063, 0.0066, 0.0076, 0.0089, 0.0100])


def random_modes(seed: int) -> tuple[tuple[float, float], np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    lo = float(rng.uniform(0, 20))
    hi = lo + float(rng.uniform(5, 500))
    m = int(rng.integers(1, 12))
    f = np.sort(rng.uniform(lo, hi, m))
    z = 10 ** rng.uniform(-3.5, -1, m)
    return (lo, hi), f, z


@pytest.mark.parametrize("rule", [r for r in RULES if r != "d-optimal"])
@pytest.mark.parametrize("seed", range(8))
def test_lines_are_n_sorted_distinct_and_span_the_band(rule, seed):
    band, f, z = random_modes(seed)
    n = int(np.random.default_rng(seed).integers(3, 600))
    d = design_lines(band, n, f, z, rule=rule)
    x = d.frequency_hz
    assert x.size == n
    assert np.all(np.diff(x) > 0)
    assert x[0] == band[0] and x[-1] == band[1]
    assert np.all((x >= band[0]) & (x <= band[1]))
    np.testing.assert_array_equal(d.half_power_lines, half_power_counts(x, f, z))


def test_d_optimal_lines_are_n_sorted_distinct_in_band():
    d = design_lines((1.0, 40.0), 60, CHAIN6_F, CHAIN6_Z, rule="d-optimal")
    x = d.frequency_hz
    assert x.size == 60 and np.all(np.diff(x) > 0) and x[0] == 1.0 and x[-1] == 40.0


@pytest.mark.parametrize("seed", range(8))
def test_each_mode_gets_its_guaranteed_lines(seed):
    band, f, z = random_modes(seed)
    d = design_lines(band, 400, f, z)
    assert np.all(d.half_power_lines >= d.guaranteed_lines)


def test_modal_rule_puts_lines_on_every_resonance():
    d = design_lines((1.9, 37.1), 200, CHAIN6_F, CHAIN6_Z)
    eq = design_lines((1.9, 37.1), 200, CHAIN6_F, CHAIN6_Z, rule="equidistant")
    # 3/4 of 200 lines over 6 modes, half of each mode's share inside its half-power band
    assert np.all(d.guaranteed_lines >= 10)
    assert np.all(d.half_power_lines >= d.guaranteed_lines)
    assert np.all(d.half_power_lines > eq.half_power_lines)


def test_dt_uniform_lines_are_uniform_on_the_circle():
    d = design_lines((0.5, 100.0), 101, [20.0], [0.01], rule="dt-uniform")
    angle = mapped_angle(d.frequency_hz, d.bilinear_scale)
    np.testing.assert_allclose(np.diff(angle), np.diff(angle)[0], rtol=1e-9)


def test_uncertainty_widens_the_lines_around_a_mode():
    narrow = design_lines((1.0, 50.0), 200, [20.0], [0.002])
    wide = design_lines((1.0, 50.0), 200, [20.0], [0.002], frequency_uncertainty=0.02)
    within = [np.sum(np.abs(d.frequency_hz - 20.2) < 0.1) for d in (narrow, wide)]
    assert within[1] > within[0]  # a mode 1 % above the expected one is covered better
    assert narrow.half_power_lines[0] > wide.half_power_lines[0]


def test_modes_outside_the_band_are_left_out():
    d = design_lines((5.0, 10.0), 50, [1.0, 7.0, 30.0], [0.01, 0.01, 0.01])
    np.testing.assert_array_equal(d.mode_frequency_hz, [7.0])


@pytest.mark.parametrize("kwargs, message", [
    ({"band_hz": (10.0, 5.0)}, "band"),
    ({"band_hz": (-1.0, 5.0)}, "band"),
    ({"band_hz": (1.0, np.inf)}, "band"),
    ({"n_lines": 2}, "number of lines"),
    ({"n_lines": 10.5}, "number of lines"),
    ({"frequency_hz": [7.0, -1.0], "damping_ratio": [0.01, 0.01]}, "frequency"),
    ({"damping_ratio": [0.0]}, "damping"),
    ({"damping_ratio": [1.0]}, "damping"),
    ({"damping_ratio": [0.01, 0.02]}, "one damping ratio"),
    ({"frequency_hz": [50.0]}, "no expected mode"),
    ({"rule": "log"}, "unknown rule"),
    ({"modal_share": 1.0}, "modal share"),
    ({"frequency_uncertainty": -0.1}, "uncertainty"),
    ({"rule": "d-optimal", "n_lines": 5000}, "at most"),
])
def test_bad_design_inputs_are_refused(kwargs, message):
    args = {"band_hz": (5.0, 10.0), "n_lines": 50, "frequency_hz": [7.0],
            "damping_ratio": [0.01]} | kwargs
    with pytest.raises(ValueError, match=message):
        design_lines(**args)


# --------------------------------------------------------------------------- the pipeline


def test_the_gram_schur_complement_survives_a_singular_row_gram():
    rng = np.random.default_rng(0)
    X = rng.standard_normal((6, 3))
    guu = X @ X.T  # rank 3 of 6: Cholesky fails
    gyu = rng.standard_normal((4, 3)) @ X.T
    gyy = gyu @ np.linalg.pinv(guu) @ gyu.T + np.eye(4)
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.cholesky(guu)
    np.testing.assert_allclose(subspace._schur(guu, gyu, gyy), np.eye(4), atol=1e-8)
    stacked = subspace._schur(np.stack([guu, np.eye(6)]), np.stack([gyu, gyu]),
                              np.stack([gyy, gyy]))
    np.testing.assert_allclose(stacked[0], np.eye(4), atol=1e-8)


def test_local_spacing_is_the_gap_around_a_frequency():
    f = np.array([1.0, 2.0, 2.1, 2.2, 5.0])
    assert local_spacing(f, 2.15) == pytest.approx(0.1)
    assert local_spacing(f, 0.0) == pytest.approx(1.0)
    assert local_spacing(f, 9.0) == pytest.approx(2.8)


def test_the_pipeline_identifies_the_modes_on_designed_lines():
    import automodal

    system = sim.damp(sim.chain(6), "rayleigh", 0.01)
    modes = sim.exact_modes(system, list(range(6)), [5])
    d = design_lines((1.9, 37.1), 200, modes.frequency_hz, modes.damping_ratio)
    H = sim.frf(system, d.frequency_hz, list(range(6)), [5], "acceleration")
    H = H + sim.complex_gaussian(H.shape, 1e-3 * sim.rms_over_lines(H), 1)
    data = automodal.FRFData(frequency=d.frequency_hz, frf=H, quantity="acceleration")
    result = automodal.identify(data, automodal.Settings(seed=1, n_bootstrap=20, jobs=1))
    f = np.array([m.frequency_hz for m in result.physical_modes])
    z = np.array([m.damping_ratio for m in result.physical_modes])
    assert f.size == 6
    np.testing.assert_allclose(f, modes.frequency_hz, rtol=1e-4)
    np.testing.assert_allclose(z, modes.damping_ratio, rtol=0.05)
    assert not any("not resolved" in w for w in result.warnings)


# --------------------------------------------------------------------------- the command


def run(*args: str):
    return CliRunner().invoke(main, ["design", *args])


BASE = ["--band", "1.9", "37.1", "--lines", "120"]


def test_design_writes_csv_and_json(tmp_path):
    out_csv, out_json = tmp_path / "l.csv", tmp_path / "sub" / "l.json"
    result = run(*BASE, "--mode", "3.84:0.01", "--mode", "11.29:0.0063",
                 "-o", str(out_csv), "-o", str(out_json))
    assert result.exit_code == 0, result.output
    lines = np.loadtxt(out_csv, skiprows=1)
    doc = json.loads(out_json.read_text())
    assert out_csv.read_text().splitlines()[0] == "frequency_hz"
    assert lines.size == 120 and doc["n_lines"] == 120 and doc["format"] == "automodal-lines"
    np.testing.assert_array_equal(lines, doc["frequency_hz"])
    assert [m["frequency_hz"] for m in doc["expected_modes"]] == [3.84, 11.29]
    assert "half-power band" in result.output


def test_design_reads_a_report_a_modes_file_and_a_csv(tmp_path):
    rng = np.random.default_rng(0)
    system = sim.damp(sim.chain(4), "rayleigh", 0.01)
    modes = sim.exact_modes(system, [0, 1, 2, 3], [3])
    freq = np.linspace(1.0, 35.0, 400)
    H = sim.add_noise(sim.frf(system, freq, [0, 1, 2, 3], [3]), 1e-3, rng)
    import automodal
    from automodal.io.modes_file import write_modes_json
    from automodal.io.report import save_report
    from automodal.report_model import Report

    data = automodal.FRFData(frequency=freq, frf=H)
    result = automodal.identify(data, automodal.Settings(seed=0, n_bootstrap=10, jobs=1))
    save_report(tmp_path / "r.json", Report.from_result(result, data))
    write_modes_json(tmp_path / "m.json", modes)
    (tmp_path / "m.csv").write_text("mode,frequency_hz,damping_ratio\n"
                                    + "".join(f"{i},{f},{z}\n" for i, (f, z) in enumerate(
                                        zip(modes.frequency_hz, modes.damping_ratio, strict=True))))
    for src in ("r.json", "m.json", "m.csv"):
        out = tmp_path / f"{src}.lines.json"
        res = run("--band", "1", "35", "--lines", "100", "--modes", str(tmp_path / src),
                  "-o", str(out), "-q")
        assert res.exit_code == 0, (src, res.output)
        doc = json.loads(out.read_text())
        got = [m["frequency_hz"] for m in doc["expected_modes"]]
        np.testing.assert_allclose(got, modes.frequency_hz, rtol=1e-3)


@pytest.mark.parametrize("args, needle", [
    (BASE + ["--mode", "3:0.01", "-o", "{tmp}/l.txt"], "give a .csv or .json"),
    (["--band", "40", "2", "--lines", "50", "--mode", "3:0.01", "-o", "{tmp}/l.csv"], "band"),
    (["--band", "2", "40", "--lines", "2", "--mode", "3:0.01", "-o", "{tmp}/l.csv"], "lines"),
    (BASE + ["--mode", "3:1", "-o", "{tmp}/l.csv"], "damping ratio"),
    (BASE + ["--mode", "3", "-o", "{tmp}/l.csv"], "F"),
    (BASE + ["--mode", "3:x", "-o", "{tmp}/l.csv"], "F"),
    (BASE + ["-o", "{tmp}/l.csv"], "no expected mode"),
    (BASE + ["--mode", "90:0.01", "-o", "{tmp}/l.csv"], "no expected mode lies in the band"),
    (BASE + ["--modes", "{tmp}/none.csv", "-o", "{tmp}/l.csv"], "no such file"),
    (BASE + ["--modes", "{tmp}/bad.csv", "-o", "{tmp}/l.csv"], "frequency_hz"),
    (BASE + ["--modes", "{tmp}/text.csv", "-o", "{tmp}/l.csv"], "row 2"),
    (BASE + ["--modes", "{tmp}/garbage.json", "-o", "{tmp}/l.csv"], "garbage.json"),
    (BASE + ["--mode", "3:0.01", "--uncertainty", "-1", "-o", "{tmp}/l.csv"], "uncertainty"),
    (BASE + ["--mode", "3:0.01", "--rule", "log", "-o", "{tmp}/l.csv"], "rule"),
    (BASE + ["--mode", "3:0.01", "-o", "{tmp}/file.csv/l.csv"], "folder"),
])
def test_design_refuses_bad_input_in_one_line(tmp_path, args, needle):
    (tmp_path / "bad.csv").write_text("f,zeta\n3,0.01\n")
    (tmp_path / "text.csv").write_text("frequency_hz,damping_ratio\nabc,0.01\n")
    (tmp_path / "garbage.json").write_text("{not json")
    (tmp_path / "file.csv").write_text("x")
    result = run(*[a.replace("{tmp}", str(tmp_path)) for a in args])
    assert result.exit_code == 2, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("automodal: error: "), result.stderr
    assert needle in lines[0]
    assert "Traceback" not in result.output
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "bad.csv", "file.csv", "garbage.json", "text.csv"]
