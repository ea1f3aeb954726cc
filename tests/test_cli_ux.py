"""What a test engineer sees and does at the command line (issue 15): the table, mode
numbers, warnings, monitoring options, output folders, and a lean ``identify``."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from automodal.cli import main

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data" / "chain6.h5"
FAST = ["--bootstrap", "6", "--seed", "1"]


def cli(*args: object):
    """Run the command line in this process; returns click's result (stdout and stderr
    apart)."""
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


# ------------------------------------------------------------------------------ imports

HEAVY = ("automodal.app.batch", "automodal.app.monitoring", "scipy.stats", "scipy.ndimage",
         "scipy.signal", "scipy.optimize", "matplotlib", "dask", "joblib", "pyuff",
         # numpy's submodules that scipy's import executes unless the command defers them
         "numpy.f2py.crackfortran", "numpy.testing._private.utils")


def _python(code: str, timeout: float) -> subprocess.CompletedProcess:
    """``code`` run by a fresh interpreter (its imports its own), its output captured."""
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=timeout)


def test_importing_the_command_line_loads_no_library():
    """``import automodal.cli`` (every command's ``--help``) and the ``identify`` command's
    module load none of the libraries: each command imports what it uses when it runs."""
    heavy = ("numpy", "scipy", "h5py", "matplotlib", "dask", "pyuff", "joblib", "skfuzzy",
             "threadpoolctl")
    code = ("import sys, automodal.cli, automodal.cli.identify_cmd\n"
            f"print(','.join(m for m in {heavy!r} if m in sys.modules))\n")
    done = _python(code, 60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "", f"imported: {done.stdout.strip()}"


def test_identify_of_one_file_imports_no_heavy_module():
    """A run on one file imports neither the batch machinery nor libraries it does not use
    (the imports of ``automodal identify`` are a large share of a small run)."""
    code = (
        "import sys\n"
        "from automodal.cli import main\n"
        "try:\n"
        f"    main(['identify', {str(SAMPLE)!r}, '--bootstrap', '4', '--quiet'])\n"
        "except SystemExit as exc:\n"
        "    assert exc.code == 0, exc.code\n"
        f"print(','.join(m for m in {HEAVY!r} if m in sys.modules))\n"
    )
    done = _python(code, 120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "", f"imported: {done.stdout.strip()}"


def test_deferred_numpy_modules_still_work_when_used():
    """A deferred module is the real module on first use; one already imported, or absent
    from numpy, is left alone."""
    code = (
        "import sys\n"
        "import numpy.testing\n"
        "from automodal.cli._startup import defer_unused_numpy_modules\n"
        "done = defer_unused_numpy_modules(('numpy.f2py', 'numpy.testing', 'numpy.no_such'))\n"
        "assert done == ['numpy.f2py'], done\n"
        "import scipy.linalg\n"
        "assert 'numpy.f2py.crackfortran' not in sys.modules\n"
        "import numpy\n"
        "assert callable(numpy.f2py.run_main)\n"
        "from numpy.f2py import crackfortran\n"
        "assert 'numpy.f2py.crackfortran' in sys.modules\n"
    )
    done = _python(code, 60)
    assert done.returncode == 0, done.stderr


# ------------------------------------------------------------------------------ the table

SISO = SAMPLE.with_name("chain8_siso.h5")


def test_table_shows_physical_modes_and_warnings_go_to_stderr(tmp_path):
    out = tmp_path / "r.json"
    done = cli("identify", SISO, "-o", out, *FAST)
    assert done.exit_code == 0, done.output
    report = json.loads(out.read_text())
    physical = [m for m in report["modes"] if m["physical"]]
    rows = done.stdout.splitlines()[2:-1]
    assert len(rows) == len(physical) < len(report["modes"])
    assert [r.split()[0] for r in rows] == [str(k) for k in range(1, len(physical) + 1)]
    assert "not shown (--all)" in done.stdout.splitlines()[-1]
    assert report["warnings"], "the test needs an input that makes a warning"
    assert done.stderr.splitlines() == [f"automodal: warning: {w}" for w in report["warnings"]]

    every = cli("identify", SISO, "--all", *FAST)
    assert len(every.stdout.splitlines()[2:-1]) == len(report["modes"])
    assert "not physical" in every.stdout


@pytest.mark.parametrize("flag", ["--quiet", "--json"])
def test_quiet_and_json_leave_the_warnings_in_the_report(flag):
    done = cli("identify", SISO, flag, *FAST)
    assert done.exit_code == 0 and done.stderr == ""
    if flag == "--quiet":
        assert done.stdout == ""
    else:
        assert json.loads(done.stdout)["warnings"]


# ------------------------------------------------------------------------------ consistency


def test_every_command_makes_missing_output_folders(tmp_path):
    """One behaviour for outputs: missing folders are made (as mkdir -p), by every command."""
    report = tmp_path / "a" / "b" / "r.h5"
    done = cli("identify", SAMPLE, "-o", report, "--plot", tmp_path / "figs" / "x", *FAST)
    assert done.exit_code == 0, done.output
    assert report.is_file() and any((tmp_path / "figs" / "x").iterdir())
    converted = cli("convert", SAMPLE, tmp_path / "c" / "d" / "x.h5", "-q")
    assert converted.exit_code == 0 and (tmp_path / "c" / "d" / "x.h5").is_file()
    drawn = cli("plot", report, "-o", tmp_path / "e" / "f.png")
    assert drawn.exit_code == 0 and (tmp_path / "e" / "f.png").is_file()
    figures = cli("plot", report, "-o", tmp_path / "e2" / "f2" / "figs")
    assert figures.exit_code == 0, figures.output
    assert (tmp_path / "e2" / "f2" / "figs" / "overview.png").is_file()
    for name in ("shapes.uff", "shapes.csv"):
        exported = cli("export", report, "-o", tmp_path / "l" / "m" / name, "-q")
        assert exported.exit_code == 0, exported.output
        assert (tmp_path / "l" / "m" / name).is_file()
    tracked = cli("track", report, "-o", tmp_path / "g" / "h.h5", "-q")
    assert tracked.exit_code == 0 and (tmp_path / "g" / "h.h5").is_file()
    simulated = cli("simulate", tmp_path / "i" / "s.h5", "--dof", "3")
    assert simulated.exit_code == 0 and (tmp_path / "i" / "s.h5").is_file()
    batch = cli("identify", tmp_path / "c" / "d", "-o", tmp_path / "j" / "k", "-q", *FAST)
    assert batch.exit_code == 0 and (tmp_path / "j" / "k" / "x.json").is_file()


@pytest.mark.parametrize("command", [
    ["identify", SAMPLE, "-o", "{blocker}/sub/r.json"],
    ["identify", SAMPLE.parent, "-o", "{blocker}/sub"],
    ["convert", SAMPLE, "{blocker}/x.h5"],
    ["identify", SAMPLE, "--plot", "{blocker}/figs"],
    ["plot", "{report}", "-o", "{blocker}/f.png"],
    ["plot", "{report}", "-o", "{blocker}/figs"],
    ["export", "{report}", "-o", "{blocker}/shapes.uff"],
    ["track", "{report}", "-o", "{blocker}/h.h5"],
    ["simulate", "{blocker}/s.h5"],
])
def test_an_output_folder_that_cannot_be_made_is_refused_before_any_work(tmp_path, command):
    blocker = tmp_path / "blocker"
    blocker.write_text("a file, not a folder")
    report = tmp_path / "r.json"
    report.write_text("{}")
    args = [str(a).format(blocker=blocker, report=report) for a in command]
    done = cli(*args)
    assert done.exit_code == 2
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("automodal: error:")
    assert "is not a folder" in lines[0]


@pytest.mark.parametrize("jobs", ["0", "-1", "-2"])
def test_jobs_below_one_is_refused(jobs):
    done = cli("identify", SAMPLE, "--jobs", jobs, *FAST)
    assert done.exit_code == 2 and "--jobs" in done.stderr


@pytest.mark.parametrize("resample, said", [
    ("lines", "bootstrap over frequency lines"),
    ("noise", "bootstrap of the noise model"),
    ("auto", "bootstrap over frequency lines"),  # chain6 has no repeated records
])
def test_resample_chooses_what_the_replicates_resample_and_the_report_says(resample, said):
    done = cli("identify", SAMPLE, "--resample", resample, "--json", *FAST)
    report = json.loads(done.stdout)
    assert done.exit_code == 0 and report["settings"]["resample"] == resample
    assert sum(said in w for w in report["warnings"]) == 1


def test_resample_refuses_an_unknown_choice_and_records_that_are_not_there():
    bad = cli("identify", SAMPLE, "--resample", "hits", *FAST)
    assert bad.exit_code == 2 and "--resample" in bad.stderr
    none = cli("identify", SAMPLE, "--resample", "records", *FAST)
    assert none.exit_code == 2 and none.stdout == ""
    assert none.stderr.count("\n") == 1 and "needs at least two records" in none.stderr


def test_band_beyond_the_data_is_said_and_a_band_outside_refused():
    wide = cli("identify", SAMPLE, "--band", "5", "1000", "--json", *FAST)
    assert wide.exit_code == 0
    report = json.loads(wide.stdout)
    hi = report["input"]["band_hz"][1]
    said = [w for w in report["warnings"] if "reaches beyond the data" in w]
    assert len(said) == 1 and said[0].startswith("the band [5, 1000] Hz")
    assert "analysed is [5" in said[0] and f"{hi:g}] Hz" in said[0]
    inside = cli("identify", SAMPLE, "--band", "5", "20", "--json", *FAST)
    assert not [w for w in json.loads(inside.stdout)["warnings"] if "beyond" in w]
    outside = cli("identify", SAMPLE, "--band", "100", "1000", *FAST)
    assert outside.exit_code == 2 and "band [100, 1000] Hz" in outside.stderr


def test_an_order_below_what_the_data_need_is_said():
    help_text = " ".join(cli("identify", "--help").stdout.split())
    assert "two per mode" in help_text
    low = cli("identify", SAMPLE, "--order", "6", "--json", *FAST)
    assert low.exit_code == 0
    said = [w for w in json.loads(low.stdout)["warnings"] if "largest model order 6" in w]
    assert len(said) == 1 and "at most 3 modes" in said[0]
    enough = cli("identify", SAMPLE, "--order", "40", "--json", *FAST)
    assert not [w for w in json.loads(enough.stdout)["warnings"] if "model order" in w]


def test_block_rows_are_raised_on_request_and_said_when_the_lines_cut_them(tmp_path):
    help_text = " ".join(cli("identify", "--help").stdout.split())
    assert "--block-rows Q" in help_text
    raised = cli("identify", SAMPLE, "--block-rows", "30", "--json", *FAST)
    assert raised.exit_code == 0
    report = json.loads(raised.stdout)
    assert report["settings"]["block_rows"] == 30
    assert report["settings"]["orders"]["block_rows"] == 30  # what the reference used
    assert report["summary"]["n_physical"] == 6
    assert not [w for w in report["warnings"] if "block rows" in w]
    cut = json.loads(cli("identify", SAMPLE, "--block-rows", "5000", "--json", *FAST).stdout)
    said = [w for w in cut["warnings"] if "block rows 5000" in w]
    assert said

    def used(orders: dict) -> list[int]:  # the block rows of every (sub-)band's reference
        parts = orders.get("sub_bands")
        return sorted(sum((used(p) for p in parts), [])) if parts else [orders["block_rows"]]

    from automodal.core.order import BOOTSTRAP_LINE_FRACTION
    from automodal.io.frf_file import read_frf

    _, ny, nu = read_frf(SAMPLE).frf.shape
    for w in said:  # each band's cut is its replicates' line budget, and is what it used
        lines = int(re.search(r"the (\d+) lines", w).group(1))
        a, b = re.search(r"at most (\d+): (\d+) used", w).groups()
        assert int(a) == int(b) == int(2 * BOOTSTRAP_LINE_FRACTION * lines * nu) // (ny + nu)
    assert sorted(int(re.search(r"(\d+) used", w).group(1)) for w in said) == used(
        cut["settings"]["orders"])
    never = tmp_path / "never.json"
    low = cli("identify", SAMPLE, "--block-rows", "1", "-o", never, *FAST)
    assert low.exit_code == 2 and "--block-rows" in low.stderr
    assert not never.exists()


def test_no_message_writes_a_range_with_a_dash():
    """Ranges are written [lo, hi] (a dash reads as a minus sign: "band -5-20 Hz")."""
    import re

    root = Path(__file__).resolve().parents[1] / "automodal"
    dashed = re.compile(r"\}-\{[^}]*\}\s*Hz|:g\}-\{|\.\dg\}-\{")
    found = [f"{p.name}: {line.strip()}" for p in root.rglob("*.py")
             for line in p.read_text(encoding="utf-8").splitlines() if dashed.search(line)]
    assert found == []


@pytest.mark.parametrize("args", [
    ["--lines", "1000000000"], ["--dof", "100000"], ["--system", "grid", "--grid", "1000", "1000"],
    ["--noise", "nan"], ["--fmax", "inf"], ["--excitation", "ambient", "--duration", "1e9"]],
    ids=["lines", "dof", "grid", "nan", "inf", "duration"])
def test_simulate_refuses_what_would_take_minutes_or_gigabytes(tmp_path, args):
    """A billion lines reached 23 GB before the system killed it; nan ended in a traceback."""
    out = tmp_path / "x.h5"
    result = cli("simulate", out, *args)
    assert result.exit_code == 2, result.output
    assert len(result.stderr.splitlines()) == 1, result.stderr
    assert not out.exists()
