"""``automodal identify`` on a malformed input: exit 2, one line on stderr, no report."""

from __future__ import annotations

import subprocess
import sys

import pytest
from frf_builders import BAD_CASES

CLI_CASES = [case for case in BAD_CASES if case.cli]


def run_identify(input_path, report_path) -> subprocess.CompletedProcess:
    """Run ``python -m automodal identify INPUT -o REPORT`` in a fresh process."""
    command = [sys.executable, "-m", "automodal", "identify", str(input_path),
               "-o", str(report_path)]
    return subprocess.run(command, capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("case", CLI_CASES, ids=[case.id for case in CLI_CASES])
def test_identify_refuses_bad_input(tmp_path, case):
    bad = tmp_path / f"{case.id}.h5"
    case.make(bad)
    report = tmp_path / "r.json"

    result = run_identify(bad, report)

    assert result.returncode == 2, result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert "Traceback" not in result.stderr
    assert lines[0].startswith("automodal: error: "), lines[0]
    assert bad.name in lines[0]
    assert not report.exists()
    assert not any(p.name.startswith(".r.json") for p in tmp_path.iterdir())


@pytest.mark.parametrize("scale", [1e200, 1e20, 1e-50, 1e-200])
def test_identify_refuses_frequencies_not_in_hz(tmp_path, scale):
    """Lines scaled by 1e200 or 1e-200 ended in a failed SVD (exit 1)."""
    from frf_builders import mutated, replace, valid_content

    bad = tmp_path / "scaled.h5"
    mutated(replace("frequency", valid_content()["frequency"] * scale))(bad)
    report = tmp_path / "r.json"
    result = run_identify(bad, report)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and "give the frequencies in Hz" in lines[0], result.stderr
    assert not report.exists()
