"""What a test engineer sees and does at the command line (issue 15): the table, mode
numbers, warnings, monitoring options, output folders, and a lean ``identify``."""

from __future__ import annotations

import json
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
         "scipy.signal", "matplotlib", "dask", "joblib")


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
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "", f"imported: {done.stdout.strip()}"


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
