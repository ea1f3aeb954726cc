"""Figures from a report (automodal.app.plots), the FRF arrays of the HDF5 report, the CLI."""

from __future__ import annotations

import copy
import json
import os
import subprocess
import sys
from pathlib import Path

os.environ["MPLBACKEND"] = "Agg"

import cases
import h5py
import numpy as np
import pytest

from automodal.app import plots
from automodal.errors import InputError
from automodal.frfdata import FRFData
from automodal.io.report import (
    MAX_FRF_LINES,
    read_report,
    read_report_arrays,
    report_dict,
    save_report,
    write_report,
)
from automodal.pipeline import identify  # noqa: E402
from automodal.result import Result  # noqa: E402
from automodal.settings import Settings  # noqa: E402

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"

# ---------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def identified() -> tuple[Result, FRFData]:
    """A real run on a 6-DOF chain (sensors on a line): physical and spurious clusters."""
    data = cases.chain6_1pct().data
    return identify(data, Settings(n_bootstrap=20, seed=1, jobs=1)), data


@pytest.fixture(scope="module")
def frf_arrays(identified) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The measured FRFs and a stand-in for the synthesized ones (1 % larger)."""
    _, data = identified
    return data.frequency, data.frf, data.frf * 1.01


@pytest.fixture(scope="module")
def report_h5(identified, frf_arrays, tmp_path_factory) -> Path:
    result, data = identified
    path = tmp_path_factory.mktemp("plots") / "r.h5"
    write_report(path, result, data, frf=frf_arrays)
    return path


@pytest.fixture(scope="module")
def report(identified) -> dict:
    result, data = identified
    return report_dict(result, data)


def run_cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run(
        [sys.executable, "-m", "automodal", *args],
        capture_output=True, text=True, env=env, cwd=cwd, timeout=300,
    )


def gids(ax) -> set[str]:
    return {a.get_gid() for a in ax.get_children() if a.get_gid()}


def n_physical(report: dict) -> int:
    return sum(1 for m in report["modes"] if m["physical"])


# ------------------------------------------------------------------ the report's arrays


def test_the_run_has_physical_and_spurious_clusters(report):
    assert 0 < n_physical(report) < len(report["modes"])


def test_hdf5_report_keeps_poles_and_frf(report_h5, identified, frf_arrays):
    result, _ = identified
    arrays = read_report_arrays(report_h5)
    poles = arrays["poles"]
    np.testing.assert_array_equal(poles["cluster"], result.poles.cluster)
    np.testing.assert_array_equal(poles["replicate"], result.poles.replicate)
    np.testing.assert_array_equal(poles["frequency_hz"], result.poles.frequency_hz)
    freq, measured, synth = frf_arrays
    lo, hi = result.band_hz
    band = (freq >= lo) & (freq <= hi)
    frf = arrays["frf"]
    assert set(frf) == {"frequency", "measured", "synthesized"}
    np.testing.assert_array_equal(frf["frequency"], freq[band])
    np.testing.assert_array_equal(frf["measured"], measured[band])
    np.testing.assert_array_equal(frf["synthesized"], synth[band])
    assert frf["measured"].dtype.kind == "c"


def test_the_report_keeps_the_sensor_geometry(report_h5, identified):
    _, data = identified
    report = read_report(report_h5)
    assert report["input"]["output_xyz"] == data.output_xyz.tolist()
    assert report["input"]["output_directions"] == data.output_directions == ["+Z"] * 6


def test_long_frf_is_decimated_to_the_band_and_the_line_limit(report, tmp_path):
    lo, hi = report["input"]["band_hz"]
    freq = np.linspace(lo - 5.0, hi, 9001)
    measured = np.ones((freq.size, 6, 1), dtype=complex) * freq[:, None, None]
    path = tmp_path / "long.h5"
    save_report(path, report, frf=(freq, measured, None))
    frf = read_report_arrays(path)["frf"]
    assert set(frf) == {"frequency", "measured"}
    assert MAX_FRF_LINES // 2 < frf["frequency"].size <= MAX_FRF_LINES
    assert frf["frequency"].min() >= lo
    assert frf["frequency"][0] == freq[freq >= lo][0]
    np.testing.assert_array_equal(frf["measured"][:, 2, 0], frf["frequency"])


def test_frf_arrays_that_do_not_fit_write_nothing(report, tmp_path):
    freq = np.linspace(1.0, 30.0, 50)
    path = tmp_path / "bad.h5"
    with pytest.raises(ValueError, match="synthesized"):
        save_report(path, report, frf=(freq, np.ones((50, 6, 1)), np.ones((50, 3, 1))))
    with pytest.raises(ValueError, match="measured"):
        save_report(path, report, frf=(freq, np.ones((49, 6, 1)), None))
    assert list(tmp_path.iterdir()) == []


def test_reports_without_arrays_give_empty_entries(identified, tmp_path):
    result, data = identified
    write_report(tmp_path / "r.json", result, data, frf=(data.frequency, data.frf, data.frf))
    write_report(tmp_path / "plain.h5", result, data)
    assert read_report_arrays(tmp_path / "r.json") == {"poles": {}, "frf": {},
                                                       "stabilization": {}}
    plain = read_report_arrays(tmp_path / "plain.h5")
    assert plain["frf"] == {} and plain["poles"] and plain["stabilization"]
    with h5py.File(tmp_path / "plain.h5", "r") as f:
        assert "frf" not in f


def test_read_report_arrays_refuses_what_is_no_report(tmp_path):
    with pytest.raises(InputError, match="no such report file"):
        read_report_arrays(tmp_path / "missing.h5")
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f.attrs["format"] = "something else"
    with pytest.raises(InputError, match="not an automodal report"):
        read_report_arrays(other)


# ---------------------------------------------------------------------- the figures


def test_pole_map_over_the_frf(report, identified, frf_arrays):
    result, _ = identified
    fig = plots.pole_map(report, result.poles, frf_arrays)
    ax, twin = fig.axes
    assert ax.get_xlabel() == "frequency (Hz)"
    assert ax.get_ylabel() == "bootstrap replicate"
    assert twin.get_yscale() == "log" and twin.get_ylabel() == "Σ|H| over channels"
    present = gids(ax)
    assert "trashbox" in present
    operational = copy.deepcopy(report)  # output-only: half spectra
    operational["input"]["attributes"]["analysis"] = "operational"
    _, twin = plots.pole_map(operational, result.poles, frf_arrays).axes
    assert twin.get_ylabel() == "Σ|G| half spectra"
    clusters = {f"cluster-{c}" for c in np.unique(result.poles.cluster) if c >= 0}
    assert clusters and clusters <= present
    labels = [t for t in ax.texts if t.get_gid() == "mode-label"]
    assert len(labels) == n_physical(report)
    assert all(t.get_text().endswith(" Hz") for t in labels)
    assert "frf-sum" in gids(twin)


def test_pole_map_from_the_read_arrays_without_frf(report_h5):
    report = read_report(report_h5)
    arrays = read_report_arrays(report_h5)
    fig = plots.pole_map(report, arrays["poles"])
    assert len(fig.axes) == 1
    trash = [a for a in fig.axes[0].collections if a.get_gid() == "trashbox"]
    assert len(trash) == 1
    assert len(trash[0].get_offsets()) == np.sum(arrays["poles"]["cluster"] == -1)


def test_frf_fit_magnitude_and_phase(report, frf_arrays):
    freq, measured, synth = frf_arrays
    fig = plots.frf_fit(report, freq, measured, synth, max_channels=3)
    mag, phase = fig.axes
    assert mag.get_yscale() == "log" and mag.get_ylabel().startswith("|H|")
    assert phase.get_yscale() == "linear" and phase.get_ylabel() == "phase (°)"
    assert phase.get_xlabel() == "frequency (Hz)"
    for ax in (mag, phase):
        kinds = [line.get_gid() for line in ax.get_lines()]
        assert kinds.count("measured") == 3 and kinds.count("synthesized") == 3
    fig = plots.frf_fit(report, freq, measured, None)
    assert [line.get_gid() for line in fig.axes[0].get_lines()].count("synthesized") == 0


def test_physicalness_bars(report):
    fig = plots.physicalness_bars(report)
    (ax,) = fig.axes
    assert ax.get_ylabel() == "physicalness" and "frequency" in ax.get_xlabel()
    bars = [p.get_gid() for p in ax.patches]
    assert bars.count("physical") == n_physical(report)
    assert bars.count("not-physical") == len(report["modes"]) - n_physical(report)
    heights = sorted(p.get_height() for p in ax.patches)
    assert heights == pytest.approx(sorted(m["physicalness"] for m in report["modes"]))
    assert any(list(line.get_ydata()) == [0.5, 0.5] for line in ax.get_lines())


def test_physicalness_legend_counts_physical_modes_below_the_threshold(report):
    """A physical mode below the threshold (a companion or weak mode the refinement's
    likelihood tests hold) is counted in the threshold's legend; none, no count."""
    def threshold_label(r):
        (ax,) = plots.physicalness_bars(r).axes
        return [t for t in ax.get_legend_handles_labels()[1] if t.startswith("threshold")][0]

    assert threshold_label(report) == "threshold 0.5"
    weak = copy.deepcopy(report)
    phys = [m for m in weak["modes"] if m["physical"]]
    phys[0]["physicalness"] = 0.4
    assert threshold_label(weak) == (
        "threshold 0.5 (1 physical below it: the refinement's likelihood tests)")


def test_mode_shapes_as_bars_and_on_the_geometry(report):
    no_xyz = copy.deepcopy(report)
    no_xyz["input"]["output_xyz"] = None
    no_xyz["input"]["mode_shape_xyz"] = None
    fig = plots.mode_shapes(no_xyz)
    assert len(fig.axes) == n_physical(report)
    ax = fig.axes[0]
    assert {p.get_gid() for p in ax.patches} == {"real", "magnitude"}
    assert [t.get_text() for t in ax.get_xticklabels()] == report["input"]["output_names"]
    fig = plots.mode_shapes(report)
    assert [ax.name for ax in fig.axes] == ["3d"] * n_physical(report)
    assert "sensors" in gids(fig.axes[0])
    xyz = np.array([[x, y, 0.0] for x in range(3) for y in range(2)])
    assert all(ax.name == "3d" for ax in plots.mode_shapes(no_xyz, xyz).axes)
    with pytest.raises(ValueError, match="xyz"):
        plots.mode_shapes(no_xyz, xyz[:4])


def test_overview_and_what_it_leaves_out(report, identified, frf_arrays):
    result, _ = identified
    fig = plots.overview(report, result.poles, frf_arrays)
    n = n_physical(report)
    assert len(fig.axes) == 2 + 2 + 1 + n  # pole map + twin, FRF x2, physicalness, shapes
    fig = plots.overview(report)
    assert len(fig.axes) == 1 + n
    empty = {**report, "modes": []}
    fig = plots.overview(empty)
    assert any("no physical mode" in t.get_text() for ax in fig.axes for t in ax.texts)


def test_save_figures_writes_the_standard_set(report_h5, tmp_path):
    report = read_report(report_h5)
    written = plots.save_figures(report, read_report_arrays(report_h5), tmp_path / "figs", dpi=50)
    assert [p.name for p in written] == [f"{name}.png" for name in plots.FIGURE_NAMES]
    for p in written:
        assert p.read_bytes()[:8] == PNG_MAGIC
    few = plots.save_figures(report, {"poles": {}, "frf": {}}, tmp_path / "few", dpi=50)
    assert [p.name for p in few] == ["overview.png", "physicalness.png", "mode_shapes.png",
                                     "automac.png"]
    assert sorted(p.name for p in (tmp_path / "few").iterdir()) == sorted(p.name for p in few)


# -------------------------------------------------------------------------- the CLI


def test_cli_plot_writes_a_png(report_h5, tmp_path):
    out = tmp_path / "fig.png"
    proc = run_cli("plot", str(report_h5), "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    assert proc.stdout.strip() == str(out)
    data = out.read_bytes()
    assert data[:8] == PNG_MAGIC and len(data) > 50_000
    assert [p.name for p in tmp_path.iterdir()] == ["fig.png"]


def test_cli_plot_default_name_and_svg(report_h5, tmp_path):
    report = tmp_path / "run.h5"
    report.write_bytes(report_h5.read_bytes())
    proc = run_cli("plot", "run.h5", "--dpi", "40", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "run.png").read_bytes()[:8] == PNG_MAGIC
    proc = run_cli("plot", str(report), "-o", str(tmp_path / "run.svg"))
    assert proc.returncode == 0, proc.stderr
    assert "<svg" in (tmp_path / "run.svg").read_text(encoding="utf-8")[:2000]


def test_cli_plot_json_report_says_what_it_leaves_out(identified, tmp_path):
    result, data = identified
    path = tmp_path / "r.json"
    write_report(path, result, data)
    proc = run_cli("plot", str(path), "-o", str(tmp_path / "r.pdf"))
    assert proc.returncode == 0, proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and str(path) in lines[0] and "no bootstrap poles" in lines[0]
    assert (tmp_path / "r.pdf").read_bytes()[:5] == b"%PDF-"


@pytest.mark.parametrize(
    ("make", "output", "message"),
    [
        (lambda d: d / "missing.h5", "fig.png", "no such report file"),
        (lambda d: d / "r.json", "fig.gif", "unknown figure type"),
        (lambda d: d / "r.json", "r.json/fig.png", "r.json is not a folder"),
        (lambda d: d / "bad.json", "fig.png", "not a valid JSON report"),
    ],
)
def test_cli_plot_bad_input_exits_2(identified, tmp_path, make, output, message):
    result, data = identified
    write_report(tmp_path / "r.json", result, data)
    (tmp_path / "bad.json").write_text("{", encoding="utf-8")
    proc = run_cli("plot", str(make(tmp_path)), "-o", str(tmp_path / output))
    assert proc.returncode == 2
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("automodal: error:") and message in lines[0]
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / output).exists()


def test_help_and_import_never_load_matplotlib():
    code = (
        "import sys\n"
        "import automodal.app.plots, automodal.io.report\n"
        "from automodal.cli import main\n"
        "try:\n"
        "    main(['--help'])\n"
        "except SystemExit:\n"
        "    pass\n"
        "print(json.dumps('matplotlib' in sys.modules))\n"
    )
    proc = subprocess.run([sys.executable, "-c", "import json\n" + code],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "plot" in proc.stdout
    assert json.loads(proc.stdout.strip().splitlines()[-1]) is False
