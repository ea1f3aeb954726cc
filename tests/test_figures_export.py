"""Issue 15 (items 4-7): stabilization diagram, residual synthesis, AutoMAC, resolution
warnings, mode-shape export (UFF 55, CSV), geometry CSV and the test date."""

from __future__ import annotations

import copy
import csv
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
from automodal.core import stabilization as st
from automodal.core.synthesis import fit_fixed_poles, modal_poles
from automodal.errors import InputError
from automodal.io.geometry import apply_to_report, read_geometry
from automodal.io.mode_export import export_modes
from automodal.io.report import build_report, load_report, save_report
from automodal.pipeline import identify, resolution_warnings
from automodal.settings import Settings


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    data = cases.chain6_1pct().data
    result = identify(data, Settings(n_bootstrap=20, seed=1, jobs=1))
    report = build_report(result, data)
    path = tmp_path_factory.mktemp("issue15") / "r.h5"
    save_report(path, report, result.poles, result.frf_fit, result.stabilization)
    return result, data, report, path


def cli(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run([sys.executable, "-m", "automodal", *args], capture_output=True,
                          text=True, env=env, timeout=300)


# ----------------------------------------------------------------------------- core


def test_stability_flags_against_the_previous_order():
    shapes = np.array([[1.0, 0.0], [0.0, 1.0]], dtype=complex)
    flags = st.stability_flags(
        np.array([10.05, 20.0]), np.array([0.0102, 0.02]), shapes,
        np.array([10.0, 25.0]), np.array([0.01, 0.02]), shapes)
    # 0.5 % and 2 % changes with the same shape: all stable; 20 -> 25 Hz: new
    assert flags[0] == st.STABLE_ALL
    assert not flags[1] & st.STABLE_FREQUENCY


def test_the_stabilization_poles_reach_the_report(run):
    result, _, _, path = run
    stab = result.stabilization
    assert len(stab) > 0 and np.all(np.diff(np.unique(stab.order)) > 0)
    # every true mode of the chain has a pole stable in all three at some order
    for f in cases.chain6_1pct().true_hz:
        near = np.abs(stab.frequency_hz - f) < 0.01 * f
        assert np.any(near & (stab.stability == st.STABLE_ALL))
    with h5py.File(path, "r") as fh:
        np.testing.assert_array_equal(fh["stabilization/order"][()], stab.order)
        assert fh["stabilization"].attrs["mac_tolerance"] == st.MAC_TOLERANCE


def test_residuals_recover_modes_outside_the_band():
    # two modes in the band, one far below and one far above: with residuals the fit of
    # the in-band poles alone is close; without them it is not
    f = np.linspace(20, 60, 400)
    w = 2 * np.pi * f
    lam = modal_poles(np.array([5.0, 30.0, 45.0, 300.0]), np.full(4, 0.01))
    jw = 1j * w[:, None]
    H = np.sum(1.0 / (jw - lam) - 1.0 / (jw - lam.conj()), axis=1) * 1j
    H = H[:, None, None] * (1j * w[:, None, None]) ** 2  # accelerance
    with_res = fit_fixed_poles(w, H, lam[1:3], power=2)
    without = fit_fixed_poles(w, H, lam[1:3], power=2, residuals=False)
    assert with_res.normalised_error[0, 0] < 1e-3
    assert without.normalised_error[0, 0] > 10 * with_res.normalised_error[0, 0]


def test_resolution_warning_below_one_and_a_half_lines(run):
    result, data, _, _ = run
    mode = result.physical_modes[0]
    f = data.frequency
    assert resolution_warnings([mode], f) == []  # 1 % damping on fine lines
    bandwidth = 2.0 * mode.damping_ratio * mode.frequency_hz
    assert resolution_warnings([mode], np.arange(0.0, 40.0, bandwidth / 1.5)) == []
    assert resolution_warnings([mode], np.arange(0.0, 40.0, bandwidth / 1.4))
    coarse = np.arange(0.0, 40.0, 1.0)  # B = 0.077 Hz against 1 Hz lines
    (text,) = resolution_warnings([mode], coarse)
    assert f"{mode.frequency_hz:.4g} Hz" in text and "1.47 line spacings" in text


# ----------------------------------------------------------------------------- figures


def test_stabilization_diagram_draws_poles_against_order(run):
    result, _, report, _ = run
    fig = plots.stabilization_diagram(report, result.stabilization, result.frf_fit)
    ax = fig.axes[0]
    assert ax.get_ylabel() == "model order" and ax.get_xlabel() == "frequency (Hz)"
    stable = next(c for c in ax.collections if c.get_gid() == "stable")
    xy = stable.get_offsets()
    sel = result.stabilization.stability == st.STABLE_ALL
    np.testing.assert_allclose(xy[:, 0], result.stabilization.frequency_hz[sel])
    np.testing.assert_allclose(xy[:, 1], result.stabilization.order[sel])
    labels = [t for t in ax.texts if t.get_gid() == "mode-label"]
    assert len(labels) == len(report.physical_modes)
    # the same number as in the table, the shape panels and the AutoMAC: 1..n by frequency
    assert sorted(t.get_text() for t in labels) == sorted(
        f"{m.mode_number}: {m.frequency_hz:.4g} Hz" for m in report.physical_modes)
    assert [m.mode_number for m in report.physical_modes] == list(
        range(1, len(report.physical_modes) + 1))
    assert any(line.get_gid() == "frf-sum" for a in fig.axes for line in a.lines)


def test_close_mode_labels_are_spread_apart():
    x = plots.spread_positions(np.array([0.5, 0.501, 0.502, 0.9]), 0.02)
    assert np.all(np.diff(x) >= 0.02 - 1e-12)
    assert abs(np.mean(x[:3]) - 0.501) < 1e-9 and x[3] == 0.9


def test_mode_colours_do_not_repeat_after_ten():
    colours = [tuple(np.round(c[:3], 6)) for c in plots.mode_colors(15)]
    assert len(set(colours)) == 15


def test_physical_mode_colours_are_never_the_grey_of_what_is_not_physical():
    """Seen on chain8_siso: mode 8 took tab10's grey, the colour of the other clusters."""
    from matplotlib.colors import to_rgb

    grey = np.array(to_rgb(plots.NON_PHYSICAL_COLOR))
    for n in (8, 9, 10, 12):
        rgb = np.array([c[:3] for c in plots.mode_colors(n)])
        assert np.all(np.ptp(rgb, axis=1) > 0.15), n  # no grey at all
        assert np.all(np.abs(rgb - grey).max(axis=1) > 0.15), n


def test_a_single_channel_shape_is_a_bar_not_a_3d_stem(run):
    _, _, report, _ = run
    one = copy.deepcopy(report)
    for mode in one.modes:
        mode.shape_real = mode.shape_real[:1]
        mode.shape_imag = mode.shape_imag[:1]
        mode.mode_shape_std = mode.mode_shape_std[:1]
    one.input.output_names = one.input.output_names[:1]
    fig = plots.mode_shapes(one, np.array([[7.0, 0.0, 0.0]]))
    ax = fig.axes[0]
    assert ax.name == "rectilinear"
    assert [t.get_text() for t in ax.get_xticklabels()] == one.input.output_names[:1]


@pytest.mark.parametrize("n", [12, 20, 40])
def test_mode_colours_past_ten_read_on_white(n):
    """Seen on grid_mimo's 12 modes: turbo's yellows made labels like '7: 22.51 Hz'
    unreadable; no colour may be lighter than tab10's olive."""
    rgb = np.array([c[:3] for c in plots.mode_colors(n)])
    luminance = rgb @ np.array([0.2126, 0.7152, 0.0722])
    assert luminance.max() <= 0.71


def test_automac_matrix(run):
    _, _, report, _ = run
    fig = plots.automac(report)
    ax = fig.axes[0]
    image = next(a for a in ax.get_images() if a.get_gid() == "automac")
    m = np.asarray(image.get_array())
    n = len(report.physical_modes)
    assert m.shape == (n, n)
    np.testing.assert_allclose(np.diag(m), 1.0)
    tags = [f"{k}: {mode.frequency_hz:.4g} Hz" for k, mode in
            enumerate(sorted(report.physical_modes, key=lambda m: m.frequency_hz), start=1)]
    assert [t.get_text() for t in ax.get_xticklabels()] == tags
    assert [t.get_text() for t in ax.get_yticklabels()] == tags
    assert ax.get_xlabel() == ax.get_ylabel() == "mode: frequency"
    values = [t for t in ax.texts if t.get_gid() == "mac-value"]
    assert len(values) == n * n and values[1].get_text() == f"{m[0, 1]:.2f}"
    assert "cannot all be" not in fig._suptitle.get_text()  # 6 channels, 6 modes


def test_automac_says_when_the_channels_are_fewer_than_the_modes(run):
    """Seen on the Weimar frame (5 channels, 11 modes): off-diagonal values near 1 are
    the sensors' limit, and the title says so."""
    report = copy.deepcopy(run[2])  # the run is shared by the module's tests
    for mode in report.physical_modes:
        mode.shape_real, mode.shape_imag = mode.shape_real[:2], mode.shape_imag[:2]
    title = plots.automac(report)._suptitle.get_text()
    assert f"2 channels for {len(report.physical_modes)} modes: the shapes cannot all be" in title


def test_frf_fit_says_channels_units_and_error(run):
    result, _, report, _ = run
    f, H, S = result.frf_fit
    fig = plots.frf_fit(report, f, H, S, max_channels=4)
    title = fig._suptitle.get_text()
    assert "4 of 6 channels" in title and "median normalised error" in title
    assert fig.axes[0].get_ylabel() == "|H| receptance (m/N)"
    names = [line.get_label() for line in fig.axes[0].lines if line.get_gid() == "measured"]
    assert all("(error " in name for name in names)
    report.input.quantity = "acceleration"
    assert "(m/s²)/N" in plots.frf_fit(report, f, H, S).axes[0].get_ylabel()
    report.input.attributes["analysis"] = "operational"
    fig = plots.frf_fit(report, f, H, S)
    assert "half spectrum" in fig.axes[0].get_ylabel()
    assert "receptance" not in fig.axes[0].get_ylabel()
    report.input.quantity = "displacement"
    del report.input.attributes["analysis"]


def test_legends_with_long_channel_names_stay_inside_the_figure(run):
    """Seen on the ModeLAB beam (channels named by their SignalCalc files): a one-row legend
    ran off the figure and squeezed the axes to half its width."""
    result, _, report, _ = run
    f, H, S = result.frf_fit
    long = copy.deepcopy(report)
    long.input.output_names = [f"accelerometer_{k}_on_the_left_flange" for k in range(H.shape[1])]
    fig = plots.frf_fit(long, f, H, S, max_channels=4)
    fig.canvas.draw()  # the Agg canvas a new Figure gets
    box = fig.bbox
    legend = fig.axes[0].get_legend().get_window_extent()
    assert box.x0 - 1 <= legend.x0 and legend.x1 <= box.x1 + 1
    assert fig.axes[0].get_window_extent().width > 0.7 * box.width
    assert len(fig.axes[0].get_legend().get_texts()) == 4 + 2  # channels, measured, synthesized


def test_shapes_show_the_spread_and_3d_axes(run):
    _, _, report, _ = run
    plain = copy.deepcopy(report)
    plain.input.output_xyz = plain.input.mode_shape_xyz = None
    bars = plots.mode_shapes(plain).axes[0]
    spread = [c for c in bars.containers if c.get_label() == "± spread"]
    assert len(spread) == 1
    segments = spread[0].lines[2][0].get_segments()
    std = plain.physical_modes[0].mode_shape_std
    np.testing.assert_allclose([s[1, 1] - s[0, 1] for s in segments], 2 * np.array(std))
    xyz = np.column_stack([np.arange(6.0), np.zeros(6), np.zeros(6)])
    ax = plots.mode_shapes(report, xyz).axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel(), ax.get_zlabel()) == ("x", "y", "z")
    scale = next(t for t in ax.texts if t.get_gid() == "shape-scale")
    assert scale.get_position()[1] == 1.0 and scale.get_va() == "top"  # clear of the x label


# ----------------------------------------------------------------------------- export


def test_uff55_round_trip(run, tmp_path):
    import pyuff

    _, _, report, _ = run
    out = tmp_path / "shapes.uff"
    assert export_modes(out, report) == len(report.physical_modes)
    sets = pyuff.UFF(str(out)).read_sets()
    sets = sets if isinstance(sets, list) else [sets]
    assert [s["type"] for s in sets] == [55] * len(report.physical_modes)
    for s, mode in zip(sets, report.physical_modes):
        np.testing.assert_allclose(s["r3"], mode.shape, rtol=1e-4, atol=1e-5)
        assert abs(abs(s["eig"]) / (2 * np.pi) - mode.frequency_hz) < 1e-4 * mode.frequency_hz
        assert s["mode_n"] == mode.mode_number  # the number the tables show, not the id


def test_csv_export_has_named_columns(run, tmp_path):
    _, _, report, _ = run
    out = tmp_path / "shapes.csv"
    export_modes(out, report, polar=True)
    with open(out, newline="") as fh:
        rows = list(csv.reader(fh))
    name = report.shape_channels[0]
    assert rows[0][:5] == ["mode", "frequency_hz", "damping_ratio", f"{name}_mag",
                           f"{name}_phase_deg"]
    assert len(rows) == 1 + len(report.physical_modes)
    assert float(rows[1][1]) == pytest.approx(report.physical_modes[0].frequency_hz)
    assert [int(r[0]) for r in rows[1:]] == list(range(1, len(report.physical_modes) + 1))


def test_export_cli_and_refusals(run, tmp_path):
    _, _, _, path = run
    done = cli("export", str(path), "-o", str(tmp_path / "s.unv"))
    assert done.returncode == 0, done.stderr
    bad = cli("export", str(path), "-o", str(tmp_path / "s.txt"))
    assert bad.returncode == 2 and "automodal: error:" in bad.stderr
    assert not (tmp_path / "s.txt").exists()


# ----------------------------------------------------------------------------- geometry


def write_geometry(path: Path, names: list[str]) -> Path:
    lines = ["node,x,y,z"] + [f"{k + 10},{0.5 * k},0,0" for k in range(len(names))]
    lines += ["channel,node,direction"] + [f"{n},{k + 10},+Y" for k, n in enumerate(names)]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_geometry_csv_reaches_the_shapes_and_the_export(run, tmp_path):
    import pyuff

    _, _, report, _ = run
    geo = read_geometry(write_geometry(tmp_path / "g.csv", report.shape_channels))
    apply_to_report(report, geo)
    assert report.input.mode_shape_nodes == list(range(10, 16))
    assert report.input.mode_shape_xyz[2] == [1.0, 0.0, 0.0]
    ax = plots.mode_shapes(report).axes[0]
    assert ax.name == "3d"
    export_modes(tmp_path / "g.uff", report)
    s = pyuff.UFF(str(tmp_path / "g.uff")).read_sets()
    s = s[0] if isinstance(s, list) else s
    np.testing.assert_array_equal(s["node_nums"], np.arange(10, 16))
    np.testing.assert_allclose(s["r2"], report.physical_modes[0].shape, rtol=1e-4, atol=1e-5)


@pytest.mark.parametrize("text, message", [
    ("1,0,0,0\n", "header"),
    ("node,x,y,z\n1,0,0\n", "3 fields"),
    ("node,x,y,z\n1,0,0,nan\n", "finite"),
    ("node,x,y,z\n1,0,0,0\nchannel,node,direction\na,1,+Q\n", "direction"),
])
def test_geometry_csv_refusals(tmp_path, text, message):
    path = tmp_path / "g.csv"
    path.write_text(text)
    with pytest.raises(InputError, match=message):
        read_geometry(path)


def test_simulate_and_convert_set_the_test_date(tmp_path):
    sim = tmp_path / "t.h5"
    done = cli("simulate", str(sim), "--lines", "200", "--test-date", "2024-05-01", "-q")
    assert done.returncode == 0, done.stderr
    with h5py.File(sim, "r") as fh:
        assert fh.attrs["test_date"] == "2024-05-01T00:00:00Z"
    out = tmp_path / "c.h5"
    done = cli("convert", str(sim), str(out), "--test-date", "2024-06-02T10:00:00+02:00", "-q")
    assert done.returncode == 0, done.stderr
    with h5py.File(out, "r") as fh:
        assert fh.attrs["test_date"] == "2024-06-02T08:00:00Z"
    bad = cli("convert", str(sim), str(tmp_path / "d.h5"), "--test-date", "yesterday")
    assert bad.returncode == 2 and "ISO 8601" in bad.stderr
    assert not (tmp_path / "d.h5").exists()


def test_plot_into_a_folder_writes_the_set(run, tmp_path):
    _, _, _, path = run
    done = cli("plot", str(path), "-o", str(tmp_path / "figs"))
    assert done.returncode == 0, done.stderr
    names = {p.stem for p in (tmp_path / "figs").iterdir()}
    assert {"stabilization", "automac", "frf_fit", "mode_shapes"} <= names
    report = load_report(path, arrays=True)
    assert report.arrays.stabilization
