"""Progress of a run (issue 14): the stages a callback receives, in order, for FRFs and for
time records; the same result with or without it; the terminal line, and nothing of it
where stderr is not a terminal."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from automodal.cli import main
from automodal.cli.progress_display import ProgressLine, progress_line, wanted
from automodal.core import simulate as sim
from automodal.core import simulate_time as st
from automodal.io.readers import read_any
from automodal.pipeline import identify
from automodal.progress import Progress, counter, tell, within
from automodal.settings import Settings

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data" / "chain6.h5"
IDENTIFY = ["checks", "orders", "reference", "bootstrap", "summary", "refinement"]
"""The stages of one identification with a noise model, in order."""


def labels(events: list[Progress]) -> list[str]:
    """The events' labels, each run of equal labels once."""
    out: list[str] = []
    for e in events:
        if not out or out[-1] != e.label:
            out.append(e.label)
    return out


def check_counts(events: list[Progress], label: str, total: int) -> None:
    """A counted stage goes from 0 to its total without going back."""
    done = [e.done for e in events if e.label == label]
    assert done[0] == 0 and done[-1] == total, done
    assert all(b >= a for a, b in zip(done, done[1:])), done
    assert {e.total for e in events if e.label == label} == {total}


# ------------------------------------------------------------------------------ events


def test_an_event_is_checked_and_labelled():
    assert Progress("bootstrap", 3, 10, "first pass").label == "first pass: bootstrap"
    assert Progress("orders").label == "orders"
    with pytest.raises(ValueError, match="unknown stage"):
        Progress("brewing")
    with pytest.raises(ValueError, match="not a count"):
        Progress("bootstrap", 11, 10)


def test_the_helpers_send_nothing_without_a_callback_and_nest_parts():
    assert counter(None, "bootstrap", 5) is None and within(None, "x") is None
    tell(None, "orders")  # no error
    seen: list[Progress] = []
    inner = within(within(seen.append, "first pass"), "sub-band 1 of 2")
    tell(inner, "orders")
    count = counter(inner, "bootstrap", 4)
    count(3)
    count(3)  # never past the total
    assert [e.label for e in seen] == ["first pass, sub-band 1 of 2: orders"] + [
        "first pass, sub-band 1 of 2: bootstrap"] * 3
    assert [e.done for e in seen[1:]] == [0, 3, 4]


# ---------------------------------------------------------------------------- pipeline


def test_frf_input_sends_the_stages_in_order_and_the_result_is_unchanged():
    data = read_any(SAMPLE)
    s = Settings(seed=1, n_bootstrap=8, jobs=1)
    events: list[Progress] = []
    with_progress = identify(data, s, progress=events.append)
    assert labels(events) == IDENTIFY
    check_counts(events, "bootstrap", 8)
    without = identify(data, s)
    assert [m.frequency_hz for m in with_progress.modes] == [m.frequency_hz for m in without.modes]
    assert np.array_equal(with_progress.poles.frequency_hz, without.poles.frequency_hz)


def test_the_stages_and_the_result_do_not_depend_on_jobs():
    data = read_any(SAMPLE)
    runs = []
    for jobs in (1, 2):
        events: list[Progress] = []
        result = identify(data, Settings(seed=2, n_bootstrap=12, jobs=jobs), events.append)
        runs.append((labels(events), result))
    assert runs[0][0] == runs[1][0] == IDENTIFY
    assert np.array_equal(runs[0][1].poles.frequency_hz, runs[1][1].poles.frequency_hz)


def test_output_only_records_send_the_first_pass_then_the_analysis():
    system = sim.damp(sim.chain(3), zeta=0.02)
    ts, _, _ = st.simulate_time_test(system, None, None, "ambient", "acceleration", 0.01, 7,
                                     duration=300.0)
    events: list[Progress] = []
    identify(ts, Settings(seed=0, n_bootstrap=6, jobs=1), events.append)
    got = labels(events)
    # half spectra are not refined (their errors are correlated across lines)
    stages = [x for x in IDENTIFY if x != "refinement"]
    first = [f"first pass: {x}" for x in ["spectra", *stages]]
    assert got[: len(first)] == first, got
    assert got[len(first):] == ["spectra", *stages], got
    check_counts(events, "first pass: bootstrap", 6)
    check_counts(events, "bootstrap", 6)


def test_records_with_forces_send_the_spectra_stage_first():
    system = sim.damp(sim.chain(3), zeta=0.02)
    ts, _, _ = st.simulate_time_test(system, None, 0, "random", "acceleration", 0.01, 3,
                                     duration=120.0)
    events: list[Progress] = []
    identify(ts, Settings(seed=0, n_bootstrap=4, jobs=1), events.append)
    assert labels(events)[:3] == ["spectra", "checks", "orders"], labels(events)


def test_run_file_reads_first_and_writes_last(tmp_path):
    from automodal.app.run import run_file

    events: list[Progress] = []
    run_file(SAMPLE, Settings(seed=1, n_bootstrap=4, jobs=1), [tmp_path / "r.json"],
             progress=events.append)
    assert labels(events) == ["reading", *IDENTIFY, "writing"]


# --------------------------------------------------------------------------- terminal


class FakeTerminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_is_drawn_only_on_a_terminal_without_quiet_or_json():
    assert wanted(False, False, FakeTerminal())
    assert not wanted(True, False, FakeTerminal())
    assert not wanted(False, True, FakeTerminal())
    assert not wanted(False, False, io.StringIO())
    with progress_line(False) as progress:
        assert progress is None


def test_the_line_is_redrawn_in_place_and_erased_at_the_end():
    term = FakeTerminal()
    with progress_line(True, term, tick_s=None) as progress:
        progress(Progress("orders"))
        progress(Progress("bootstrap", 5, 10))
    out = term.getvalue()
    assert "orders ..." in out and "bootstrap [############............] 5/10" in out
    assert out.endswith("\r\x1b[K") and "\n" not in out  # one line, erased
    line = ProgressLine(FakeTerminal(), tick_s=None)
    assert line.text(Progress("bootstrap", 10, 10, "first pass"), 2.0).startswith(
        "first pass: bootstrap [" + "#" * 24 + "] 10/10")
    line.close()


def test_the_command_line_without_a_terminal_shows_no_progress(tmp_path):
    """CliRunner's stderr is not a terminal: stdout and stderr are those of a run without
    progress (the table, the warnings), and the report has nothing of it."""
    out = tmp_path / "r.json"
    done = CliRunner().invoke(main, ["identify", str(SAMPLE), "--bootstrap", "6", "--seed", "1",
                                     "-o", str(out)], catch_exceptions=False)
    assert done.exit_code == 0
    for text in (done.stdout, done.stderr, out.read_text()):
        assert "\r" not in text and "\x1b" not in text and "bootstrap [" not in text
    assert done.stderr.startswith("automodal: warning:")


def test_a_split_band_sends_each_sub_band_s_stages(monkeypatch):
    from automodal.core import sub_bands

    monkeypatch.setattr(sub_bands, "WORK_LIMIT", 1e4)  # every band with a few peaks splits
    events: list[Progress] = []
    result = identify(read_any(SAMPLE), Settings(seed=0, n_bootstrap=6, jobs=1), events.append)
    n = len(result.orders["sub_bands"])
    assert n >= 2
    got = labels(events)
    assert got[:2] == ["checks", "orders"]  # the whole band's, before the split
    # each part says its stages: a whole run, or checks and orders before its own split
    parts: dict[str, list[str]] = {}
    for label in got[2:]:
        prefix, _, stage = label.rpartition(": ")
        parts.setdefault(prefix, []).append(stage)
    assert all(stages in (IDENTIFY, ["checks", "orders"]) for stages in parts.values()), parts
    tops = [p for p in parts if "," not in p]
    assert tops == [f"sub-band {i} of {n}" for i in range(1, n + 1)]
    for prefix, stages in parts.items():
        if stages == IDENTIFY:
            check_counts(events, f"{prefix}: bootstrap", 6)
