"""Monitoring (issue 6): baseline checks, batch runs, histories and a Dask cluster.

A damped 3-DOF chain is "measured" (simulated with new noise) ten times, with one spring
10 % softer from the 7th measurement on, and once more for the baseline. Small systems and
20 bootstrap replicates keep the whole file to a few seconds per identification.
"""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from report_schema import schema_errors

from automodal.app import monitoring as mon
from automodal.app.batch import expand_inputs, report_stems, run_batch
from automodal.cli import main
from automodal.core import simulate as sim
from automodal.core.matching import ModeTable
from automodal.io.frf_file import write_frf
from automodal.io.history import is_history_file, read_history, write_history
from automodal.io.report import read_report
from automodal.report_model import Report
from automodal.settings import Settings

N_MEASUREMENTS = 10
FIRST_DAMAGED = 7
BOOTSTRAP = ["--bootstrap", "20", "--seed", "0"]


# ------------------------------------------------------------------------------ helpers


def soften(system: sim.MechanicalSystem, i: int, j: int, factor: float) -> sim.MechanicalSystem:
    """The system with the spring between DOFs ``i`` and ``j`` scaled by ``factor``."""
    K = system.K.copy()
    change = (1.0 - factor) * -K[i, j]
    K[i, i] -= change
    K[j, j] -= change
    K[i, j] += change
    K[j, i] += change
    return sim.MechanicalSystem(system.M, K, system.C, system.xyz, system.meta)


HEALTHY = sim.damp(sim.chain(3), "rayleigh", 0.01)
DAMAGED = soften(HEALTHY, 0, 1, 0.9)
LINES = sim.frequency_lines(1.25 * sim.natural_frequencies_hz(HEALTHY).max(), 300)


def measure(path: Path, damaged: bool, seed: int, day: int) -> Path:
    """Write one simulated measurement with a test date."""
    data, _ = sim.simulate_test(DAMAGED if damaged else HEALTHY, None, [2], LINES,
                                noise=0.01, seed=seed)
    data.attributes["test_date"] = f"2026-03-{day:02d}T06:00:00"
    write_frf(path, data)
    return path


def cli(*args: str):
    """Run the command line in this process; returns click's result."""
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> dict[str, Path]:
    """The baseline report and a folder of ten measurements (damage from the 7th on)."""
    root = tmp_path_factory.mktemp("site")
    incoming = root / "incoming"
    incoming.mkdir()
    for k in range(1, N_MEASUREMENTS + 1):
        measure(incoming / f"m{k:02d}.h5", k >= FIRST_DAMAGED, seed=k, day=k)
    base_frf = measure(root / "baseline.h5", False, seed=100, day=1)
    result = cli("identify", base_frf, "-o", root / "baseline.json", "-q", *BOOTSTRAP)
    assert result.exit_code == 0, result.output
    return {"root": root, "incoming": incoming, "baseline": root / "baseline.json"}


def table(freqs, stds=None, shapes=None, physical=None) -> ModeTable:
    """A mode table for the unit tests (shapes default to unit vectors)."""
    f = np.asarray(freqs, dtype=float)
    n = f.size
    return ModeTable(
        ids=np.arange(1, n + 1),
        frequency_hz=f,
        frequency_std_hz=np.full(n, 1e-3) if stds is None else np.asarray(stds, float),
        frequency_ci95_hz=np.column_stack([f - 2e-3, f + 2e-3]),
        damping_ratio=np.full(n, 0.01),
        damping_std=np.full(n, 1e-4),
        damping_ci95=np.full((n, 2), 0.01),
        physical=np.ones(n, bool) if physical is None else np.asarray(physical, bool),
        shapes=np.eye(max(n, 3), dtype=complex)[:n] if shapes is None else shapes,
        cluster=np.arange(n),
    )


# ------------------------------------------------------------------------------ unit


def test_compare_flags_moved_missing_and_reshaped_modes_only():
    base = table([5.0, 12.0, 20.0])
    same = mon.compare(base, table([5.001, 12.002, 19.999]))
    assert not same.flagged and [e.status for e in same.entries] == ["ok"] * 3

    moved = mon.compare(base, table([5.0, 11.8, 20.0]))
    assert moved.flagged
    assert [(e.baseline_id, e.reasons) for e in moved.flagged_entries] == [(2, ["frequency"])]
    assert moved.flagged_entries[0].allowed_shift_hz == pytest.approx(0.0025 * 12.0)

    # listed out of order and with mode 2 gone: the assignment still pairs 5-5 and 20-20
    gone = mon.compare(base, table([20.0, 5.0], shapes=np.eye(3, dtype=complex)[[2, 0]]))
    assert {e.baseline_id: e.status for e in gone.entries} == {1: "ok", 2: "missing", 3: "ok"}
    assert gone.flagged

    shapes = np.eye(3, dtype=complex)
    shapes[1] = [0.6, 0.8, 0.0]  # MAC 0.64 with the baseline's second shape
    reshaped = mon.compare(base, table([5.0, 12.0, 20.0], shapes=shapes))
    assert [(e.baseline_id, e.reasons) for e in reshaped.flagged_entries] == [(2, ["shape"])]

    extra = mon.compare(base, table([5.0, 12.0, 20.0, 27.0], shapes=np.eye(4)[:, :3]))
    assert not extra.flagged and extra.entries[-1].status == "new"


def test_compare_uses_the_bootstrap_spread_and_ignores_non_physical_modes():
    base = table([10.0], stds=[0.02])
    wide = mon.compare(base, table([10.12], stds=[0.02]))  # 0.12 Hz < 5 x 0.028
    assert not wide.flagged
    narrow = mon.compare(table([10.0], stds=[1e-4]), table([10.12], stds=[1e-4]))
    assert narrow.flagged
    hidden = mon.compare(base, table([10.0], physical=[False]))
    assert hidden.entries[0].status == "missing"
    assert "not called physical" in hidden.entries[0].message


def test_compare_refuses_shapes_on_other_channels():
    with pytest.raises(ValueError, match="channels"):
        mon.compare(table([5.0]), table([5.0], shapes=np.ones((1, 4), complex)))


def test_report_time_prefers_the_test_date():
    report = _report("2026-05-01T00:00:00Z", [], {"date": "2024-05-01T10:30:00"})
    assert report.test_time() == ("2024-05-01T10:30:00Z", "test_date")
    assert report.test_date() == "2024-05-01T10:30:00Z"
    report.input.attributes = {"date": "yesterday"}
    assert report.test_time() == ("2026-05-01T00:00:00Z", "created")
    assert report.test_date() is None


def test_report_stems_avoid_collisions():
    stems = report_stems([Path("a/x.h5"), Path("a/x.uff"), Path("a/y.h5"), Path("b/y.h5")])
    assert stems == ["x.h5", "x.uff", "y.h5", None]


# ------------------------------------------------------------------------------ must show


def test_remeasured_structure_passes_and_softer_spring_is_flagged(site, tmp_path):
    again = cli("identify", site["incoming"] / "m01.h5", "-o", tmp_path / "again.json",
                "--baseline", site["baseline"], *BOOTSTRAP)
    assert again.exit_code == 0, again.output
    assert schema_errors(read_report(tmp_path / "again.json")) == []
    block = read_report(tmp_path / "again.json")["monitoring"]
    assert block["flagged"] is False and block["n_flagged"] == 0
    assert block["baseline"]["path"] == str(site["baseline"])
    assert {e["status"] for e in block["modes"]} == {"ok"}

    softer = cli("identify", site["incoming"] / f"m{FIRST_DAMAGED:02d}.h5", "-o",
                 tmp_path / "softer.json", "--baseline", site["baseline"], *BOOTSTRAP)
    assert softer.exit_code == 3, softer.output
    block = read_report(tmp_path / "softer.json")["monitoring"]
    assert block["flagged"] is True
    moved = {e["baseline_mode_number"]: e for e in block["modes"] if e["flagged"]}
    assert sorted(moved) == [1, 2, 3]  # the physical modes by frequency, whatever their ids
    # the softer spring lowers every mode of the 3-DOF chain by 0.6-2.7 %
    true_shift = (sim.natural_frequencies_hz(DAMAGED) / sim.natural_frequencies_hz(HEALTHY) - 1)
    assert len(moved) == int(np.sum(np.abs(true_shift) > 0.004)) == 3
    for entry in moved.values():
        assert entry["reasons"] == ["frequency"] and entry["relative_shift"] < -0.004
        assert f"mode {entry['baseline_mode_number']} (" in softer.stdout
    shifts = sorted(e["relative_shift"] for e in moved.values())
    np.testing.assert_allclose(shifts, sorted(true_shift), atol=1e-3)

    quiet = cli("identify", site["incoming"] / f"m{FIRST_DAMAGED:02d}.h5", "--baseline",
                site["baseline"], "-q", *BOOTSTRAP)
    assert quiet.exit_code == 3 and quiet.stdout == ""


def test_batch_with_a_corrupt_file_reports_the_good_ones_and_exits_2(site, tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    for name in ("m01.h5", "m02.h5"):
        shutil.copy(site["incoming"] / name, folder / name)
    (folder / "m03.h5").write_bytes(b"\x89HDF\r\n\x1a\n truncated")
    out = tmp_path / "out"

    run = cli("identify", folder, "-o", out, "--format", "both", *BOOTSTRAP)
    assert run.exit_code == 2, run.output
    assert sorted(p.name for p in out.iterdir()) == [
        "m01.h5", "m01.json", "m02.h5", "m02.json", "summary.csv", "summary.json"]
    assert run.stderr.count("\n") == 1 and "m03.h5" in run.stderr
    summary = json.loads((out / "summary.json").read_text())
    status = {Path(f["file"]).name: f for f in summary["files"]}
    assert [status[n]["status"] for n in ("m01.h5", "m02.h5", "m03.h5")] == ["ok", "ok", "failed"]
    assert status["m03.h5"]["error"] and "\n" not in status["m03.h5"]["error"]
    assert status["m01.h5"]["n_physical"] == 3 and len(status["m01.h5"]["frequencies_hz"]) == 3
    rows = list(csv.DictReader((out / "summary.csv").open()))
    assert [r["status"] for r in rows] == ["ok", "ok", "failed"]
    for name in ("m01.json", "m01.h5"):
        assert schema_errors(read_report(out / name)) == []
    assert rows[0]["test_date"] == "2026-03-01T06:00:00Z"
    assert len(rows[0]["frequencies_hz"].split()) == 3

    before = (out / "m01.json").stat().st_mtime_ns
    again = cli("identify", str(folder / "*.h5"), "-o", out, "--format", "both", "-q", *BOOTSTRAP)
    assert again.exit_code == 2 and again.stdout == ""
    summary = json.loads((out / "summary.json").read_text())
    assert [f["status"] for f in summary["files"]] == ["skipped", "skipped", "failed"]
    assert (out / "m01.json").stat().st_mtime_ns == before

    (folder / "m03.h5").unlink()
    forced = cli("identify", folder, "-o", out, "--force", "-q", "--jobs", "1", *BOOTSTRAP)
    assert forced.exit_code == 0, forced.output
    assert json.loads((out / "summary.json").read_text())["counts"]["ok"] == 2


def test_history_of_ten_measurements_flags_from_the_seventh_on(site, tmp_path):
    reports = tmp_path / "reports"
    run = cli("identify", site["incoming"], "-o", reports, "--baseline", site["baseline"],
              "-q", *BOOTSTRAP)
    assert run.exit_code == 3, run.output
    summary = json.loads((reports / "summary.json").read_text())
    expected = ["ok"] * (FIRST_DAMAGED - 1) + ["flagged"] * (N_MEASUREMENTS - FIRST_DAMAGED + 1)
    assert [f["status"] for f in summary["files"]] == expected

    history_path = tmp_path / "history.h5"
    tracked = cli("track", reports, "--baseline", site["baseline"], "-o", history_path)
    assert tracked.exit_code == 3, tracked.output  # flagged, as identify --baseline
    assert "flagged: mode 1, mode 2, mode 3" in tracked.stdout
    history = read_history(history_path)
    assert history.times[0] == "2026-03-01T06:00:00Z" and set(history.time_sources) == {"test_date"}
    assert history.flagged.tolist() == [k >= FIRST_DAMAGED for k in range(1, N_MEASUREMENTS + 1)]
    assert history.n_modes == 3 and not history.missing.any()
    assert np.all(np.isfinite(history.frequency_hz)) and np.all(history.frequency_std_hz > 0)
    assert history.mode_flagged[FIRST_DAMAGED - 1:].all()

    figure = tmp_path / "trend.png"
    drawn = cli("plot", history_path, "-o", figure)
    assert drawn.exit_code == 0, drawn.output
    assert figure.stat().st_size > 10_000


def test_history_file_round_trip_and_plot_gids(tmp_path):
    base = _report("2026-01-01T00:00:00Z", [_mode(1, 5.0), _mode(2, 12.0)])
    later = [_report(f"2026-01-0{d}T00:00:00Z", [_mode(1, 5.0), _mode(2, f)])
             for d, f in ((2, 12.0), (3, 11.5))]
    history = mon.build_history(later[::-1], ["day3.json", "day2.json"], base, "base.json")
    assert history.labels == ["day2.json", "day3.json"]  # sorted by time
    assert history.mode_flagged.tolist() == [[False, False], [False, True]]
    path = write_history(tmp_path / "h.h5", history)
    assert is_history_file(path) and not is_history_file(tmp_path / "nothing.h5")
    back = read_history(path)
    assert back.times == history.times and back.labels == history.labels
    np.testing.assert_array_equal(back.frequency_hz, history.frequency_hz)
    assert back.thresholds == history.thresholds

    from automodal.app.plots import trend

    fig = trend(back)
    gids = {c.get_gid() for ax in fig.axes for c in ax.collections}
    assert "flagged" in gids


def _mode(i: int, f: float) -> dict:
    return {"id": i, "frequency_hz": f, "frequency_std_hz": 1e-3,
            "frequency_ci95_hz": [f - 2e-3, f + 2e-3], "damping_ratio": 0.01,
            "damping_std": 1e-4, "damping_ci95": [0.0098, 0.0102], "physicalness": 0.9,
            "physical": True, "n_members": 20,
            "mode_shape": {"real": [1.0 if k == i else 0.0 for k in (1, 2)], "imag": [0.0, 0.0]},
            "mode_shape_std": [0.0, 0.0], "mpc": 1.0}


def _report(created: str, modes: list[dict], attributes: dict | None = None) -> Report:
    """A small hand-made report (two output channels) as the model."""
    return Report.from_dict({
        "format": "automodal-report", "version": 1, "automodal_version": "0.1.0",
        "created": created,
        "input": {"path": None, "sha256": None, "n_freq": 100, "n_outputs": 2, "n_inputs": 1,
                  "band_hz": [1.0, 30.0], "quantity": "displacement",
                  "output_names": ["y1", "y2"], "input_names": ["u1"],
                  "attributes": attributes or {}},
        "settings": {"seed": 0, "n_bootstrap": 20},
        "modes": modes,
        "trashbox": {"n_members": 0},
        "summary": {"n_physical": len(modes), "n_clusters": len(modes), "n_bootstrap": 20,
                    "runtime_s": 0.1},
        "warnings": [],
    })


def test_bad_batch_usage_exits_2(site, tmp_path):
    no_out = cli("identify", site["incoming"])
    assert no_out.exit_code == 2 and "-o OUTDIR" in no_out.stderr
    nothing = cli("identify", str(tmp_path / "*.h5"), "-o", tmp_path / "out")
    assert nothing.exit_code == 2 and "no input file" in nothing.stderr
    single = cli("identify", site["incoming"] / "m01.h5", "--dask-scheduler", "tcp://x:1")
    assert single.exit_code == 2 and "batch" in single.stderr
    bad_base = cli("identify", site["incoming"] / "m01.h5", "--baseline", tmp_path / "no.json")
    assert bad_base.exit_code == 2 and "no.json" in bad_base.stderr


def test_batch_on_a_dask_cluster(site, tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    files = expand_inputs(str(site["incoming"] / "m0[12].h5"))
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        result = run_batch(files, tmp_path, Settings(n_bootstrap=20),
                           scheduler_address=cluster.scheduler_address)
    assert [o.status for o in result.outcomes] == ["ok", "ok"]
    assert (tmp_path / "m01.json").is_file() and (tmp_path / "m02.json").is_file()
    assert json.loads(result.summary_json.read_text())["counts"]["ok"] == 2


def test_a_dask_worker_in_a_folder_of_its_own_gets_absolute_paths(site, tmp_path, monkeypatch):
    """Relative inputs and output folder on a cluster whose worker runs elsewhere: every
    input was "no such file" and the reports were written beside the worker. The tasks get
    the caller's absolute paths; the outcomes name the files as the caller gave them."""
    distributed = pytest.importorskip("dask.distributed")
    worker_dir = tmp_path / "worker"
    worker_dir.mkdir()
    here = tmp_path / "caller"
    (here / "incoming").mkdir(parents=True)
    for name in ("m01.h5", "m02.h5"):
        shutil.copy(site["incoming"] / name, here / "incoming" / name)

    class Done:
        def __init__(self, value):
            self.value = value

        def result(self):
            return self.value

    class WorkerElsewhere:  # runs each task at once, in the worker's own folder
        def __init__(self, address, **kwargs):
            pass

        def submit(self, fn, *args, pure=True, **kwargs):
            monkeypatch.chdir(worker_dir)
            try:
                return Done(fn(*args, **kwargs))
            finally:
                monkeypatch.chdir(here)

        def close(self):
            pass

    monkeypatch.setattr(distributed, "Client", WorkerElsewhere)
    monkeypatch.chdir(here)
    files = expand_inputs("incoming/*.h5")
    result = run_batch(files, "out", Settings(n_bootstrap=20), scheduler_address="tcp://x:1")
    assert [o.status for o in result.outcomes] == ["ok", "ok"], result.outcomes
    assert [o.file for o in result.outcomes] == [str(Path("incoming") / "m01.h5"),
                                                 str(Path("incoming") / "m02.h5")]
    assert result.outcomes[0].reports == [str(Path("out") / "m01.json")]
    assert (here / "out" / "m01.json").is_file() and (here / "out" / "m02.json").is_file()
    assert not any(worker_dir.iterdir())


def test_track_over_a_batch_folder_named_by_a_shell_glob(site, tmp_path):
    """``automodal track reports/*.json`` after a batch: the shell's list names the batch's
    summary.json too, which is left out (it exited 2: "not an automodal report"); a file
    called summary.json that is no batch summary is still read, and refused."""
    from automodal.app.batch import SUMMARY_FORMAT
    from automodal.cli.track_cmd import BATCH_SUMMARY_FORMAT

    assert BATCH_SUMMARY_FORMAT == SUMMARY_FORMAT
    files = expand_inputs(str(site["incoming"] / "m0[12].h5"))
    out = tmp_path / "reports"
    run_batch(files, out, Settings(n_bootstrap=20))
    named = sorted(out.glob("*.json"))
    assert out / "summary.json" in named
    run = cli("track", *named, "--baseline", site["baseline"], "-o", tmp_path / "h.h5")
    assert run.exit_code == 0, run.output
    assert "2 reports" in run.output
    fake = tmp_path / "other" / "summary.json"
    fake.parent.mkdir()
    fake.write_text('{"format": "something else"}')
    run = cli("track", *named, fake, "--baseline", site["baseline"], "-o", tmp_path / "g.h5")
    assert run.exit_code == 2 and "summary.json" in run.stderr


def test_a_baseline_without_physical_modes_and_other_bad_monitoring_usage_exit_2(site, tmp_path):
    """A baseline with no physical mode would pass every check (a baseline made from a
    pure-noise measurement): refused, as are non-finite thresholds (an internal error
    before) and a history file name that is a folder (an internal error before)."""
    report = json.loads(site["baseline"].read_text())
    for mode in report["modes"]:
        mode["physical"] = False
        mode["mode_number"] = None
    empty = tmp_path / "empty.json"
    empty.write_text(json.dumps(report))
    m01 = site["incoming"] / "m01.h5"
    run = cli("identify", m01, "-o", tmp_path / "r.json", "--baseline", empty, *BOOTSTRAP)
    assert run.exit_code == 2 and "no physical mode" in run.stderr
    assert not (tmp_path / "r.json").exists()
    good = cli("identify", m01, "-o", tmp_path / "g.json", *BOOTSTRAP)
    assert good.exit_code == 0
    run = cli("track", tmp_path / "g.json", "--baseline", empty, "-o", tmp_path / "h.h5")
    assert run.exit_code == 2 and "no physical mode" in run.stderr
    for option in ("--min-mac", "--shift-sigmas", "--min-shift-percent"):
        for value in ("nan", "inf"):
            run = cli("track", tmp_path / "g.json", "--baseline", site["baseline"], option,
                      value, "-o", tmp_path / "h.h5")
            assert run.exit_code == 2, (option, value)
            assert "not a finite number" in run.stderr or "not in the range" in run.stderr
    (tmp_path / "folder.h5").mkdir()
    run = cli("track", tmp_path / "g.json", "--baseline", site["baseline"], "-o",
              tmp_path / "folder.h5")
    assert run.exit_code == 2 and "is a folder" in run.stderr
    assert not (tmp_path / "h.h5").exists()


def test_thresholds_from_the_command_line(site, tmp_path):
    damaged = site["incoming"] / f"m{FIRST_DAMAGED:02d}.h5"
    wide = ["--min-shift-percent", "5", "--shift-sigmas", "1000", "--min-mac", "0.5"]
    run = cli("identify", damaged, "-o", tmp_path / "d.json", "--baseline", site["baseline"],
              *wide, *BOOTSTRAP)
    assert run.exit_code == 0, run.output  # a 10 % softer spring moves the modes < 3 %
    block = read_report(tmp_path / "d.json")["monitoring"]
    assert block["thresholds"]["min_relative_shift"] == pytest.approx(0.05)
    assert block["thresholds"]["k_sigma"] == 1000 and block["thresholds"]["min_mac"] == 0.5

    alone = cli("identify", damaged, "--min-mac", "0.5", *BOOTSTRAP)
    assert alone.exit_code == 2 and "--baseline" in alone.stderr

    out = tmp_path / "reports"
    out.mkdir()
    shutil.copy(tmp_path / "d.json", out / "d.json")
    strict = cli("track", out, "--baseline", site["baseline"], "-o", tmp_path / "h.h5", "-q")
    assert strict.exit_code == 3 and strict.stdout == ""
    lenient = cli("track", out, "--baseline", site["baseline"], "-o", tmp_path / "h.h5", *wide)
    assert lenient.exit_code == 0, lenient.output
    assert read_history(tmp_path / "h.h5").thresholds.min_relative_shift == pytest.approx(0.05)


@pytest.mark.parametrize("command", ["identify", "track"])
def test_threshold_defaults_in_the_help_are_those_of_thresholds(command):
    text = " ".join(cli(command, "--help").stdout.split())
    th = mon.Thresholds()
    assert f"Default {th.k_sigma:g}." in text
    assert f"Default {100 * th.min_relative_shift:g}." in text
    assert f"Default {th.min_mac:g}." in text


def test_trend_without_test_dates_is_drawn_in_report_order(tmp_path):
    base = _report("2026-01-01T00:00:00Z", [_mode(1, 5.0), _mode(2, 12.0)])
    # a batch makes its reports within seconds: by time they would fall on one point
    later = [_report(f"2026-01-01T00:00:0{d}Z", [_mode(1, 5.0), _mode(2, f)])
             for d, f in ((2, 12.0), (3, 11.5), (4, 11.9))]
    history = mon.build_history(later, ["a.json", "b.json", "c.json"], base, "base.json")
    assert set(history.time_sources) == {"created"}

    from automodal.app.plots import trend

    fig = trend(history)
    ax = fig.axes[0]
    x = ax.lines[0].get_xdata()
    assert list(x) == [1, 2, 3]
    notes = [t for a in fig.axes for t in a.texts if t.get_gid() == "no-test-date"]
    assert len(notes) == 1 and "3 of 3 reports have no test date" in notes[0].get_text()

    dated = mon.build_history(
        [_report("2026-01-01T00:00:00Z", [_mode(1, 5.0), _mode(2, 12.0)],
                 {"test_date": f"2026-02-0{d}"}) for d in (1, 2)],
        ["a.json", "b.json"], base, "base.json")
    fig = trend(dated)
    assert not [t for a in fig.axes for t in a.texts if t.get_gid() == "no-test-date"]


def test_history_without_mode_numbers_reads_them_as_one_to_m(tmp_path):
    base = _report("2026-01-01T00:00:00Z", [_mode(1, 5.0), _mode(2, 12.0)])
    history = mon.build_history([base], ["a.json"], base, "base.json")
    assert history.mode_numbers.tolist() == [1, 2]
    path = write_history(tmp_path / "h.h5", history)
    import h5py

    with h5py.File(path, "a") as f:
        del f["modes/number"]
    assert read_history(path).mode_numbers.tolist() == [1, 2]
