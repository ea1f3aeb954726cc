"""Benchmark: end-to-end ``automodal identify`` on the command line, interpreter start included,
and the same cases through the peer, sdypy-EMA's LSCF.

Cases (each a simulated test with known modes, written by ``automodal simulate``; the
simulation is not timed):

* ``a``: 6-DOF chain, 6 outputs, 1 input, 1000 lines, 1 % noise;
* ``b``: 8 x 10 grid of masses (80 DOFs), 40 outputs, 3 inputs, 3000 lines, 1 % noise;
* ``c``: roving hammer: 9-DOF chain, 1 accelerometer (DOF 5), 9 hit points, 51 201 lines;
* ``d`` (only with ``--cases d``: it takes minutes): 10 x 10 grid, 100 outputs, 3 inputs,
  8000 lines, 1 % noise: the largest input a user plausibly has.

For each case the script runs ``automodal identify FILE`` (default settings: 100 bootstrap
replicates, seed 0) as a child process ``--repeat`` times and reports the MEDIAN wall time
and every run's (``time.perf_counter`` around the whole child, so interpreter start, imports
and file reading count) and the child's peak resident set size (GNU ``/usr/bin/time -f %M``:
the largest of the child and its reaped worker processes, not their sum; see ``run_child``).
The physical modes of the printed table are matched one-to-one to the true modes (within 1 %
in frequency, closest pairs first): "true modes found" are the matched ones, "false" the
physical rows left unmatched.

**Peer** (cases a and b, ``PEER_CASES``; ``pip install -e '.[bench]'`` installs sdypy-EMA):
the FRFs of the case go through sdypy-EMA's LSCF in a fresh interpreter (this file run with
``--sdypy-child``), from FRF arrays read from a ``.npz`` to poles selected:
``EMA.Model(frf, freq, lower=f[0], upper=f[-1], pol_order_high, frf_form)``,
``get_poles('lscf')``, ``select_closest_poles(approx, f_window)``. ``EMA.Model`` takes a 2-D
FRF array (locations x lines) only, so every output-input pair is one row ("location"): 6
rows for case a, 40 x 3 = 120 rows for case b. sdypy-EMA needs a person to pick the poles on
a stability chart; here it is handed the true natural frequencies rounded to 3 significant
digits instead (its only non-interactive way to pick poles), which is more help than
automodal gets. Its picks are counted like automodal's rows: distinct poles picked, matched
one-to-one to the true modes within 1 %; the picked poles left unmatched are its false modes
(a pole picked for two guesses counts once).

The peer cases are INTERLEAVED: for each of the ``--repeat`` rounds, automodal runs on the
case, then sdypy-EMA on the same case, each as a child process timed with its interpreter
start; the report gives the medians of the rounds (and lists every run) and the ratio of the
medians, automodal / sdypy-EMA. The goal (issue 13): automodal, with its full bootstrap, at
most 0.8x the peer's wall time, at least as many true modes and no more false ones.

Extra figures:

* **Replicates against one identification** (cases a and b): in this process, the pipeline's
  own preparation (band, reciprocity, channel scaling, line weights) is repeated, and
  ``automodal.core.replicates.run_replicates`` (the 100 replicates, with the pipeline's
  arguments) is timed against one ``automodal.core.subspace.identify`` on the full data at
  the reference order and block rows that ``automodal.pipeline.identify`` reports in
  ``result.orders`` (minimum of ``--repeat`` calls, warm).
* **Compute only**: one in-process ``pipeline.identify`` (from the replicates part) against
  sdypy-EMA's time from arrays to poles selected (median of its runs).

Run ``python benchmarks/bench_e2e.py --help`` for the options.
"""

from __future__ import annotations

# Only the standard library at module level: the same file is the sdypy-EMA child process,
# whose import time is part of what is measured.
import argparse
import datetime
import json
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# ---------------------------------------------------------------------------- settings

CASES = {
    "a": {
        "label": "a: 6-DOF chain",
        "simulate": ["--system", "chain", "--dof", "6", "--outputs", "all", "--inputs", "6",
                     "--lines", "1000", "--noise", "0.01", "--seed", "1"],
    },
    "b": {
        "label": "b: 8x10 grid",
        "simulate": ["--system", "grid", "--grid", "8", "10", "--outputs", "1-40",
                     "--inputs", "1,40,80", "--lines", "3000", "--noise", "0.01",
                     "--seed", "1"],
    },
    "c": {
        "label": "c: roving hammer, 9-DOF chain",
        "simulate": ["--system", "chain", "--dof", "9", "--outputs", "5", "--inputs", "1-9",
                     "--lines", "51201", "--quantity", "acceleration", "--noise", "0.01",
                     "--seed", "1"],
    },
    "d": {
        "label": "d: 10x10 grid, 100 outputs",
        "simulate": ["--system", "grid", "--grid", "10", "10", "--outputs", "1-100",
                     "--inputs", "1,50,100", "--lines", "8000", "--noise", "0.01",
                     "--seed", "3"],
    },
}
"""Case d, a 100-channel test of 8000 lines (the largest plausible input), is run only when
asked for (``--cases d``): it takes minutes (2026-12-02: 206 s, 2.0 GB, 91 of 100 modes;
before that day's change to the sub-bands' cap 147 s, 73 of 100; session 43 of
``benchmarks/results_issue13.md``)."""
DEFAULT_CASES = "a,b,c"
RATIO_CASES = ("a", "b")  # replicates against one identification
PEER_CASES = ("a", "b")  # sdypy-EMA comparison, interleaved with automodal
MATCH_TOL = 0.01  # relative frequency tolerance of a found mode
N_BOOTSTRAP = 100  # automodal's default, and what is timed

SDYPY = {
    "a": {"pol_order_high": 60, "f_window": 5.0},
    "b": {"pol_order_high": 120, "f_window": 5.0},
}
"""sdypy-EMA's settings per peer case.

``pol_order_high``: LSCF fits common-denominator polynomials of orders 2, 4, ...,
2 ``pol_order_high``, so at most ``pol_order_high`` modes (conjugate pairs) can appear. 60 is
the value of sdypy-EMA's documented example and is ample for case a's 6 modes; case b has 80
modes in its band, so it needs more than 80: 120 (1.5 x the modes). One run each on case b
(sdypy-EMA 0.31.0, f_window 5, 2 cores; true modes found / false / wall s): order 80: 45 / 2
/ 2.3; 100: 57 / 1 / 3.8; 120: 59 / 1 / 6.2; 140: 63 / 2 / 9.4; 160: 62 / 3 / 14.2. With
f_window 50, orders 100 and 120 found 4 true modes.

``f_window``: ``select_closest_poles`` refines each guess within windows of ``f_window // i``
Hz (those over 3 Hz), then 2 Hz. Its default 50 Hz suits kHz data; on case a (modes
3.8-30.9 Hz) it pulled the picks onto wrong poles, so 5 Hz is passed, which leaves only the
last window, +-2 Hz: the narrowest sdypy-EMA allows (one more choice a person makes for it).
Case b's modes are as little as 0.05 Hz apart, so that window holds several modes."""


# ---------------------------------------------------------------------------- helpers


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(
        description="Time `automodal identify` end to end (interpreter start included) on "
        "simulated tests (a, b, c; d on request), interleaved with sdypy-EMA's LSCF on cases "
        "a and b, and the bootstrap against one identification; print Markdown tables."
    )
    ap.add_argument("--repeat", type=int, default=5,
                    help="runs per measurement: child processes report the median wall time "
                    "(automodal and sdypy-EMA interleaved, one of each per round), in-process "
                    "timings the minimum (default 5)")
    ap.add_argument("--cases", default=DEFAULT_CASES,
                    help=f"comma-separated subset of {','.join(CASES)} (default {DEFAULT_CASES})")
    ap.add_argument("--out", metavar="FILE.md", help="also write the report to this file")
    ap.add_argument("--workdir", metavar="DIR",
                    help="where the simulated tests are written (default: a temporary folder, "
                    "removed at the end)")
    ap.add_argument("--sdypy-child", metavar="NPZ", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    args.cases = [c.strip() for c in args.cases.split(",") if c.strip()]
    bad = [c for c in args.cases if c not in CASES]
    if bad:
        ap.error(f"unknown case(s) {', '.join(bad)}: choose from {', '.join(CASES)}")
    if args.repeat < 1:
        ap.error("--repeat must be at least 1")
    return args


def automodal_cmd() -> list[str]:
    """The ``automodal`` console script if it is on PATH, else ``python -m automodal``."""
    exe = shutil.which("automodal")
    return [exe] if exe else [sys.executable, "-m", "automodal"]


GNU_TIME = "/usr/bin/time"


def peak_method() -> str:
    """How the children's peak RSS is measured (see :func:`run_child`)."""
    if os.access(GNU_TIME, os.X_OK):
        return f"`{GNU_TIME} -f %M` (KiB) around each child"
    return "`os.wait4` ru_maxrss (at least this script's own size: see run_child)"


def run_child(cmd: list[str], cwd: str | Path | None = None) -> dict:
    """Run ``cmd`` to completion; wall time, the child's peak RSS (MB), stdout, stderr.

    The peak RSS comes from GNU time's ``%M`` (``ru_maxrss`` of the command, in KiB: the
    larger of the command and its reaped worker processes, not their sum). The child's own
    ``os.wait4`` usage is not used when GNU time is there: a child started from this
    process inherits this process's high-water RSS at ``exec`` (measured: a 500 MB parent
    made ``/bin/true`` peak at 515 MB), so it would report this script's size once the
    script has grown. Without GNU time, ``os.wait4`` is the fall-back.
    """
    use_time = os.access(GNU_TIME, os.X_OK)
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err, \
            tempfile.NamedTemporaryFile("r", suffix=".rss") as rss:
        full = [GNU_TIME, "-f", "%M", "-o", rss.name, *cmd] if use_time else cmd
        t0 = time.perf_counter()
        proc = subprocess.Popen(full, stdout=out, stderr=err, stdin=subprocess.DEVNULL, cwd=cwd)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        stdout = out.read().decode(errors="replace")
        stderr = err.read().decode(errors="replace")
        report = rss.read().split()
    if proc.returncode != 0:
        raise RuntimeError(
            f"{' '.join(cmd)} exited with {proc.returncode}:\n{stderr[-2000:]}"
        )
    if use_time:
        kib = float(report[-1])
    else:
        kib = usage.ru_maxrss if sys.platform != "darwin" else usage.ru_maxrss / 1024
    return {"wall": wall, "peak_mb": kib / 1024.0, "stdout": stdout, "stderr": stderr}


def median(xs: list[float]) -> float:
    """The median (mean of the middle two for an even count)."""
    ys = sorted(xs)
    k = len(ys) // 2
    return ys[k] if len(ys) % 2 else 0.5 * (ys[k - 1] + ys[k])


def timed_min(fn, repeat: int) -> tuple[float, float, object]:
    """Minimum and first wall time of ``repeat`` calls of ``fn``, and its last value."""
    times, value = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        value = fn()
        times.append(time.perf_counter() - t0)
    return min(times), times[0], value


ROW = re.compile(r"^\s*(\d+|-)\s+([0-9.eE+-]+)\s+±\s+\S+\s+\S+\s+±\s+\S+")


def physical_frequencies(table: str) -> tuple[list[float], int]:
    """Frequencies of the physical modes in ``automodal identify``'s table (the rows with a
    mode number; ``--all`` adds the other clusters with ``-``), and the number of rows."""
    freqs, rows = [], 0
    for line in table.splitlines():
        m = ROW.match(line)
        if not m:
            continue
        rows += 1
        if m.group(1) != "-":
            freqs.append(float(m.group(2)))
    return freqs, rows


def match_modes(found: list[float], true: list[float], tol: float = MATCH_TOL) -> tuple[int, int]:
    """One-to-one matches of ``found`` to ``true`` frequencies within ``tol`` (relative),
    closest pairs first; returns (true modes matched, found modes left over)."""
    pairs = sorted(
        (abs(f - t) / t, i, j)
        for i, f in enumerate(found)
        for j, t in enumerate(true)
        if abs(f - t) <= tol * t
    )
    used_f, used_t = set(), set()
    for _, i, j in pairs:
        if i not in used_f and j not in used_t:
            used_f.add(i)
            used_t.add(j)
    return len(used_t), len(found) - len(used_f)


def load_average() -> str:
    try:
        return "{:.2f} {:.2f} {:.2f}".format(*os.getloadavg())
    except OSError:
        return "n/a"


def blas_line() -> str:
    """numpy version and its BLAS, in one line."""
    import numpy as np

    parts = [f"numpy {np.__version__}"]
    try:
        from threadpoolctl import threadpool_info

        for info in threadpool_info():
            if info.get("user_api") == "blas":
                parts.append(
                    f"{info.get('internal_api')} {info.get('version')}"
                    f" ({info.get('architecture')}, {info.get('threading_layer')},"
                    f" {info.get('num_threads')} threads)"
                )
    except ImportError:  # pragma: no cover - threadpoolctl comes with scikit-learn
        parts.append("BLAS: threadpoolctl not installed")
    env = [f"{k}={os.environ[k]}" for k in ("OPENBLAS_CORETYPE", "OPENBLAS_NUM_THREADS",
                                            "OMP_NUM_THREADS") if k in os.environ]
    if env:
        parts.append("env " + " ".join(env))
    return "; ".join(parts)


def git_state() -> str:
    root = Path(__file__).resolve().parent.parent
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root,
                              capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                               cwd=root, capture_output=True, text=True,
                               check=True).stdout.split("\n")
        changed = [ln[3:] for ln in dirty if ln.strip()]
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + (f" with uncommitted changes in {', '.join(changed)}" if changed else "")


def fmt_s(x: float) -> str:
    return f"{x:.2f}" if x >= 0.1 else f"{x * 1000:.1f} ms"


# ---------------------------------------------------------------------------- the parts


def simulate_case(key: str, workdir: Path) -> tuple[Path, list[str], list[float]]:
    """Write case ``key``'s FRF file (untimed); its path, the command, the true frequencies."""
    path = workdir / f"{key}.h5"
    cmd = automodal_cmd() + ["simulate", str(path), *CASES[key]["simulate"], "-q"]
    run_child(cmd)
    modes = json.loads(path.with_suffix(".modes.json").read_text())
    return path, cmd, [float(f) for f in modes["frequency_hz"]]


def cli_figures(runs: list[dict], cmd: list[str], true_f: list[float], load: str) -> dict:
    """Median wall time and mode counts of ``automodal identify`` runs (child processes)."""
    counts = []
    for r in runs:
        phys, rows = physical_frequencies(r["stdout"])
        counts.append((len(phys), rows, *match_modes(phys, true_f)))
    n_phys, rows, matched, extra = counts[0]
    summary = runs[0]["stdout"].strip().splitlines()[-1] if runs[0]["stdout"].strip() else ""
    return {
        "cmd": cmd, "wall": median([r["wall"] for r in runs]),
        "walls": [r["wall"] for r in runs], "peak_mb": max(r["peak_mb"] for r in runs),
        "n_physical": n_phys, "n_rows": rows, "matched": matched, "extra": extra,
        "same_counts": len(set(counts)) == 1,
        "n_true": len(true_f), "summary": summary, "load": load,
    }


def peer_figures(runs: list[dict], cmd: list[str], true_f: list[float], error: str | None,
                 load: str) -> dict:
    """Median wall time, the picks and their counts of the sdypy-EMA runs."""
    if not runs:
        return {"cmd": cmd, "error": error, "load": load}
    infos = [json.loads(r["stdout"].strip().splitlines()[-1]) for r in runs]
    info = infos[0]
    nat, xi, keys = info["nat_freq"], info["nat_xi"], [tuple(k) for k in info["pole_ind"]]
    # one entry per distinct pole: a pole picked for two guesses is one mode
    distinct = {}
    for f, k in zip(nat, keys):
        distinct.setdefault(k, f)
    picked = list(distinct.values())
    matched, extra = match_modes(picked, true_f)
    aim = [abs(f - t) / t for f, t in zip(nat, true_f)]  # pick i was aimed at true mode i
    unmatched = [f for f in picked if all(abs(f - t) > MATCH_TOL * t for t in true_f)]
    return {
        "cmd": cmd, "error": error, "load": load, "info": info,
        "wall": median([r["wall"] for r in runs]), "walls": [r["wall"] for r in runs],
        "peak_mb": max(r["peak_mb"] for r in runs),
        "import_s": median([i["import_s"] for i in infos]),
        "poles_s": median([i["poles_s"] for i in infos]),
        "select_s": median([i["select_s"] for i in infos]),
        "compute_s": median([i["compute_s"] for i in infos]),
        "same_picks": all(i["nat_freq"] == nat for i in infos),
        "n_picks": len(nat), "n_distinct": len(picked), "matched": matched, "extra": extra,
        "n_on_target": sum(e <= MATCH_TOL for e in aim), "max_aim_err": max(aim),
        "far_from_any": unmatched, "nat_freq": nat, "nat_xi": xi,
    }


def bench_case(key: str, path: Path, true_f: list[float], repeat: int,
               npz: Path | None) -> tuple[dict, dict | None]:
    """``repeat`` rounds of ``automodal identify FILE``, each followed by the sdypy-EMA child
    on the same case when ``npz`` is given (interleaved); both as child processes."""
    am_cmd = automodal_cmd() + ["identify", str(path)]
    peer_cmd = None
    if npz is not None:
        peer_cmd = [sys.executable, str(Path(__file__).resolve()), "--sdypy-child", str(npz)]
    load = load_average()
    am_runs, peer_runs, peer_error = [], [], None
    for i in range(repeat):
        am_runs.append(run_child(am_cmd))
        line = f"    round {i + 1}: automodal {am_runs[-1]['wall']:.2f} s"
        if peer_cmd is not None and peer_error is None:
            try:
                peer_runs.append(run_child(peer_cmd))
                line += f", sdypy-EMA {peer_runs[-1]['wall']:.2f} s"
            except RuntimeError as exc:  # e.g. not installed: automodal's runs go on
                peer_error = str(exc).strip().splitlines()[-1]
                print(f"    sdypy-EMA failed (pip install -e '.[bench]'?): {exc}",
                      file=sys.stderr)
        print(line, flush=True)
    cli = cli_figures(am_runs, am_cmd, true_f, load)
    peer = None if peer_cmd is None else peer_figures(peer_runs, peer_cmd, true_f,
                                                      peer_error, load)
    return cli, peer


def bench_replicates(path: Path, repeat: int) -> dict:
    """``run_replicates`` (100 replicates) against one full-data ``subspace.identify`` at
    the reference order, with the arguments ``automodal.pipeline.identify`` uses."""
    import numpy as np

    from automodal import pipeline
    from automodal.core import bootstrap, replicates, subspace
    from automodal.io.frf_file import read_frf
    from automodal.settings import Settings

    data = read_frf(str(path))
    settings = Settings(seed=0, n_bootstrap=N_BOOTSTRAP)
    t_pipe, _, result = timed_min(lambda: pipeline.identify(data, settings), 1)
    if "sub_bands" in result.orders:  # no one model of the band to compare against
        return {"t_pipeline": t_pipe, "split": len(result.orders["sub_bands"])}
    n_hi = int(result.orders["reference"])
    q = int(result.orders["block_rows"])

    # the pipeline's own preparation (pipeline.prepare)
    prep = pipeline.prepare(data, settings, [])
    z, T, Hs, lw = prep.z, prep.T, prep.Hs, prep.line_weights
    N, ny, nu = Hs.shape
    assert q == subspace.block_rows(n_hi, ny), "block rows differ from the pipeline's"
    basis = subspace.row_basis(z, q)
    rng = np.random.default_rng(settings.seed)
    weights = bootstrap.line_weights(N, settings.n_bootstrap, rng) * lw[None, :]

    t_one, t_one_first, _ = timed_min(
        lambda: subspace.identify(z, Hs, n_hi, T, q=q, weights=lw, estimate_bd_=True), repeat
    )
    from threadpoolctl import threadpool_limits

    def one_single_thread():
        with threadpool_limits(1):
            return subspace.identify(z, Hs, n_hi, T, q=q, weights=lw, estimate_bd_=True)

    t_one1, _, _ = timed_min(one_single_thread, repeat)
    t_rep, t_rep_first, reps = timed_min(
        lambda: replicates.run_replicates(basis, Hs, n_hi, T, weights, settings.jobs), repeat
    )
    t_rep1, _, _ = timed_min(
        lambda: replicates.run_replicates(basis, Hs, n_hi, T, weights, 1), repeat
    )
    jobs = replicates.replicate_workers(settings.jobs, basis, Hs, n_hi, settings.n_bootstrap)

    # where the replicates' time goes: the one Gram product, and the stacked
    # eigenproblems alone (one thread), which no exact replicate model can skip
    with threadpool_limits(1):
        t_gram, _, sums = timed_min(lambda: subspace.gram_sums(basis, Hs, weights), repeat)
        S = subspace.schur_complement(sums, slice(0, settings.n_bootstrap))
        O, _ = subspace.observability_from_schur(S, n_hi)
        A, _ = subspace.shift_invariance(O, ny, basis)
        t_eigh, _, _ = timed_min(lambda S=S: np.linalg.eigh(S), repeat)
        t_eig, _, _ = timed_min(lambda A=A: np.linalg.eig(A), repeat)
    del S, O, A, sums

    def textbook():
        # method.md section 1 as written: LQ of the real-stacked data matrix, SVD of L22,
        # A and C by shift invariance, then B, D by the stacked linear least squares
        with threadpool_limits(1):
            l22 = subspace.projected_output_qr(basis, Hs, lw)
            O, _ = subspace.observability_from_l22(l22, n_hi)
            A, C = subspace.shift_invariance(O, ny, basis)
            return subspace._estimate_bd_stacked(z, Hs, A, C, True, lw)

    t_text, _, _ = timed_min(textbook, repeat)
    return {
        "N": N, "ny": ny, "nu": nu, "n_hi": n_hi, "q": q, "basis": result.orders["basis"],
        "t_pipeline": t_pipe, "runtime_s": result.runtime_s,
        "t_one": t_one, "t_one_first": t_one_first, "t_one_1thread": t_one1,
        "t_rep": t_rep, "t_rep_first": t_rep_first, "t_rep_1job": t_rep1, "jobs": jobs,
        "n_qr": sum(r.path == "qr" for r in reps),
        "t_gram": t_gram, "t_eigh": t_eigh, "t_eig": t_eig, "t_textbook": t_text,
    }


def write_peer_input(key: str, path: Path, true_f: list[float], workdir: Path) -> Path:
    """The FRFs of ``path`` as sdypy-EMA's ``Model`` takes them, in a ``.npz``: a 2-D array,
    one row ("location") per output-input pair (row ``o * n_inputs + i``), one column per
    line above 0 Hz; with the guesses and this case's settings."""
    import numpy as np

    from automodal.io.frf_file import read_frf

    data = read_frf(str(path))
    keep = data.frequency > 0
    H = data.frf[keep]  # (lines, outputs, inputs)
    frf = H.reshape(H.shape[0], -1).T  # (outputs * inputs, lines)
    approx = np.array([float(f"{f:.3g}") for f in true_f])
    npz = workdir / f"{path.stem}_sdypy.npz"
    np.savez(npz, frf=frf, freq=data.frequency[keep], approx=approx,
             quantity=np.array(data.quantity),
             pol_order_high=np.array(SDYPY[key]["pol_order_high"]),
             f_window=np.array(SDYPY[key]["f_window"]))
    return npz


def sdypy_child(npz: str) -> None:
    """The peer run in a fresh interpreter: FRF arrays -> LSCF poles -> closest poles."""
    t0 = time.perf_counter()
    import warnings

    import numpy as np
    from sdypy import EMA

    t_import = time.perf_counter() - t0
    d = np.load(npz)
    frf, freq, approx = d["frf"], d["freq"], d["approx"]
    order, f_window = int(d["pol_order_high"]), float(d["f_window"])
    form = {"displacement": "receptance", "velocity": "mobility",
            "acceleration": "accelerance"}[str(d["quantity"])]
    t1 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = EMA.Model(frf=frf, freq=freq, lower=float(freq[0]), upper=float(freq[-1]),
                          pol_order_high=order, frf_form=form)
        model.get_poles(method="lscf", show_progress=False)
        t2 = time.perf_counter()
        model.select_closest_poles(list(approx), f_window=f_window)
    t3 = time.perf_counter()
    print(json.dumps({
        "import_s": t_import, "poles_s": t2 - t1, "select_s": t3 - t2, "compute_s": t3 - t1,
        "nat_freq": [float(x) for x in model.nat_freq],
        "nat_xi": [float(x) for x in model.nat_xi],
        "pole_ind": [[int(a), int(b)] for a, b in model.pole_ind],
        "shape": list(frf.shape), "pol_order_high": order, "f_window": f_window,
        "version": getattr(EMA, "__version__", "?"),
    }))


# ---------------------------------------------------------------------------- report


def one_fit(r: dict) -> float:
    """The single identification's time: the faster of default BLAS threads and one."""
    return min(r["t_one"], r["t_one_1thread"])


def goal_met(am: dict, pr: dict) -> str:
    """Issue 13's goal: wall time ratio <= 0.8, at least as many true modes, no more false."""
    checks = [am["wall"] / pr["wall"] <= 0.8, am["matched"] >= pr["matched"],
              am["extra"] <= pr["extra"]]
    names = ["time", "true modes", "false modes"]
    missed = [n for n, ok in zip(names, checks) if not ok]
    return "yes" if not missed else "no (" + ", ".join(missed) + ")"


def splits_of(meta: dict) -> dict:
    """The cases identified in sub-bands (their in-process time only), kept in ``meta``."""
    return meta.get("splits", {})


def render_peers(meta: dict, cli: dict, ratios: dict, peers: dict) -> list[str]:
    """The peer section: automodal against sdypy-EMA, case by case."""
    keys = list(peers)
    out = [f"## Peer: sdypy-EMA LSCF, interleaved with automodal (case"
           f"{'s' if len(keys) > 1 else ''} {', '.join(keys)})", ""]
    version = next((pr["info"]["version"] for pr in peers.values() if "info" in pr), "?")
    out += [f"sdypy-EMA {version}: `EMA.Model(frf, freq, lower=f[0], upper=f[-1],"
            " pol_order_high, frf_form)`, `get_poles('lscf')`,"
            " `select_closest_poles(approx, f_window)`, in a fresh interpreter, FRF arrays"
            " read from a .npz. `EMA.Model` takes a 2-D FRF array (locations x lines) only:"
            " every output-input pair is one row (case b: 40 outputs x 3 inputs = 120 rows)."
            " **sdypy-EMA cannot pick poles by itself**: a person picks them on a stability"
            " chart; here it is given the true natural frequencies rounded to 3 significant"
            " digits, an f_window chosen for these tests (its default of 50 Hz picked wrong"
            " poles on case a) and a polynomial order large enough for the case's modes."
            " automodal gets no help (default settings, 100 bootstrap replicates).", "",
            f"Each round runs automodal, then sdypy-EMA, on the same case (child processes,"
            f" interpreter start included); rounds: {meta['repeat']}; medians. True modes"
            f" found = one-to-one matches within {MATCH_TOL:.0%} of a true natural frequency;"
            " false = automodal's physical rows, or sdypy-EMA's distinct picked poles, left"
            " unmatched.", ""]
    out += ["| case | automodal median wall s | sdypy-EMA median wall s |"
            " **ratio automodal / sdypy-EMA** | true modes found: automodal / sdypy-EMA |"
            " false modes: automodal / sdypy-EMA | goal met (ratio <= 0.8, found >=,"
            " false <=) |",
            "|---|---:|---:|---:|---:|---:|---|"]
    for key, pr in peers.items():
        am = cli.get(key)
        n_true = len(meta["true"][key])
        if "info" not in pr:
            out.append(f"| {CASES[key]['label']} | {am['wall']:.2f} | failed | | "
                       f"{am['matched']} / - (of {n_true}) | {am['extra']} / - | |")
            continue
        out.append(
            f"| {CASES[key]['label']} | {am['wall']:.2f} | {pr['wall']:.2f} |"
            f" **{am['wall'] / pr['wall']:.2f}** |"
            f" {am['matched']} / {pr['matched']} (of {n_true}) |"
            f" {am['extra']} / {pr['extra']} | {goal_met(am, pr)} |"
        )
    out += ["", "### Details", ""]
    out += ["| case | tool | all runs, wall s | peak MB | import s (median) |"
            " compute s (median) | setup |",
            "|---|---|---|---:|---:|---|---|"]
    for key, pr in peers.items():
        am, ar = cli.get(key), ratios.get(key) or splits_of(meta).get(key)
        if "info" in pr:
            info = pr["info"]
            out.append(
                f"| {key} | sdypy-EMA | {', '.join(f'{w:.2f}' for w in pr['walls'])} |"
                f" {pr['peak_mb']:.0f} | {pr['import_s']:.2f} | {pr['compute_s']:.2f}"
                f" (poles {pr['poles_s']:.2f}, selection {pr['select_s']:.2f}) |"
                f" FRF {info['shape'][0]} rows x {info['shape'][1]} lines,"
                f" pol_order_high={info['pol_order_high']}, f_window={info['f_window']:g} |"
            )
        else:
            error = str(pr["error"]).replace("|", "/")
            out.append(f"| {key} | sdypy-EMA | failed: {error} | | | | |")
        out.append(
            f"| {key} | automodal | {', '.join(f'{w:.2f}' for w in am['walls'])} |"
            f" {am['peak_mb']:.0f} | | "
            + (f"{ar['t_pipeline']:.2f} (`pipeline.identify`, in process, one call)" if ar
               else "") + " | default settings |"
        )
    out.append("")
    for key, pr in peers.items():
        if "info" not in pr:
            continue
        ar = ratios.get(key) or splits_of(meta).get(key)
        line = f"* {key}: "
        if ar:
            line += (f"compute only (arrays in memory): {ar['t_pipeline']:.2f} s /"
                     f" {pr['compute_s']:.2f} s = {ar['t_pipeline'] / pr['compute_s']:.2f};")
        line += (f" sdypy-EMA: {pr['n_picks']} guesses -> {pr['n_distinct']} distinct poles"
                 f" ({pr['n_picks'] - pr['n_distinct']} picked twice or more);"
                 f" {pr['n_on_target']} picks within {MATCH_TOL:.0%} of the true mode they were"
                 f" aimed at (largest relative error {pr['max_aim_err']:.1e});"
                 f" picks within {MATCH_TOL:.0%} of no true mode:"
                 f" {len(pr['far_from_any'])}")
        if not pr["same_picks"]:
            line += "; the picks differed between runs (the first run's are counted)"
        out.append(line + ".")
    out.append("")
    for key, pr in peers.items():
        if "info" not in pr:
            continue
        picks = zip(pr["nat_freq"], pr["nat_xi"])
        out += [f"sdypy-EMA's picks, case {key} (Hz, damping %):"
                f" {', '.join(f'{f:.4f} ({100 * x:.2f})' for f, x in picks)}.", ""]
    out += ["Commands:", "", "```sh"]
    out += [" ".join(pr["cmd"]) for pr in peers.values()]
    out += ["```", ""]
    return out


def render(meta: dict, cli: dict, ratios: dict, peers: dict) -> str:
    out = ["# automodal end-to-end benchmark", ""]
    out += [f"* date: {meta['date']}", f"* machine: {meta['machine']}; nproc {meta['nproc']}",
            f"* Python {meta['python']}; {meta['blas']}",
            f"* automodal: git {meta['git']}",
            f"* repeats: {meta['repeat']} (child processes: median wall time, automodal and"
            f" sdypy-EMA interleaved round by round; in-process timings: minimum; peak RSS:"
            f" largest of the runs, {meta['peak_method']})",
            f"* load average (1, 5, 15 min) at start: {meta['load_start']};"
            f" at end: {meta.get('load_end', 'n/a')}", ""]
    if meta["simulate"]:
        out += ["Test files (not timed):", "", "```sh"]
        out += [" ".join(c) for c in meta["simulate"]]
        out += ["```", ""]
    if cli:
        out += ["## `automodal identify FILE` (child process, interpreter start included)", ""]
        out += ["| case | lines | outputs | inputs | median wall s | peak MB | physical modes found"
                " / true modes | physical rows not matching a true mode | all runs, s |",
                "|---|---:|---:|---:|---:|---:|---:|---:|---|"]
        for key, r in cli.items():
            c = CASES[key]
            out.append(
                f"| {c['label']} | {meta['dims'][key][0]} | {meta['dims'][key][1]} |"
                f" {meta['dims'][key][2]} | {r['wall']:.2f} | {r['peak_mb']:.0f} |"
                f" {r['matched']} / {r['n_true']} | {r['extra']} |"
                f" {', '.join(f'{w:.2f}' for w in r['walls'])} |"
            )
        varied = [k for k, r in cli.items() if not r["same_counts"]]
        if varied:
            out += ["", f"Mode counts differed between runs in case(s) {', '.join(varied)};"
                    " the table gives the first run's."]
        out += ["", "Commands (default settings: 100 replicates, seed 0, all cores):", "", "```sh"]
        out += [" ".join(r["cmd"]) for r in cli.values()]
        out += ["```", "", "Summary lines:", ""]
        out += [f"* {k}: `{r['summary']}` (load before: {r['load']})" for k, r in cli.items()]
        out += ["", f"'found' = a row marked physical within {MATCH_TOL:.0%} of a true natural"
                " frequency (one-to-one). Peak MB (MiB) from " + meta["peak_method"] + ":"
                " the larger of the identify process and its reaped worker processes.", ""]
    if ratios:
        out += ["## 100 replicates against one full-data identification", ""]
        out += ["| case | N | ny | nu | n_ref | q | one `subspace.identify` s"
                " (default BLAS threads / 1 thread) | `run_replicates` s (jobs) |"
                " **ratio** | `run_replicates` 1 job s | ratio 1 job |"
                " first call (cold) s: identify / replicates |"
                " whole `pipeline.identify` s (one call) |",
                "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|"]
        for key, r in ratios.items():
            one = one_fit(r)
            out.append(
                f"| {key} | {r['N']} | {r['ny']} | {r['nu']} | {r['n_hi']} | {r['q']} |"
                f" {fmt_s(r['t_one'])} / {fmt_s(r['t_one_1thread'])} |"
                f" {fmt_s(r['t_rep'])} ({r['jobs']}) |"
                f" **{r['t_rep'] / one:.2f}** | {fmt_s(r['t_rep_1job'])} |"
                f" {r['t_rep_1job'] / one:.2f} |"
                f" {fmt_s(r['t_one_first'])} / {fmt_s(r['t_rep_first'])} |"
                f" {r['t_pipeline']:.2f} |"
            )
        out += ["", "Target: 100 replicates <= 3x one full-data identification at the reference"
                " order. One identification = `subspace.identify(z, Hs, n_ref, T, q=q,"
                " weights=lw, estimate_bd_=True)` (row basis, projection, A/C, B/D), timed"
                " with the default BLAS threads and with one (each replicate uses one); the"
                " ratios divide by the faster of the two;"
                " replicates = `replicates.run_replicates(basis, Hs, n_ref, T, weights, jobs)`"
                " with the pipeline's basis and weights (Gram sums + 100 small problems), jobs"
                " as the pipeline chooses them (`jobs=None`) and with 1 job. Minimum of the"
                " repeats, in this process (warm imports; the 'cold' column is the first call)."
                " The replicates run in worker threads (stacked LAPACK calls release the"
                " GIL), each with one BLAS thread.", ""]
        for key, r in ratios.items():
            out.append(f"* {key}: basis {r['basis']}; replicates on the QR fall-back path:"
                       f" {r['n_qr']} of {N_BOOTSTRAP}; load before: {r['load']}")
        out += ["", "### Where the replicates' time goes, and the textbook identification", "",
                "| case | Gram product, 100 replicates, 1 thread s | stacked `eigh` (q ny)"
                " x100, 1 thread s | stacked `eig` (n_ref) x100, 1 thread s | floor: (eigh +"
                " eig) / jobs s | floor / one identification | textbook Algorithm 2 fit s |"
                " ratio replicates / textbook fit |",
                "|---|---:|---:|---:|---:|---:|---:|---:|"]
        for key, r in ratios.items():
            one = one_fit(r)
            floor = (r["t_eigh"] + r["t_eig"]) / r["jobs"]
            out.append(
                f"| {key} | {fmt_s(r['t_gram'])} | {fmt_s(r['t_eigh'])} |"
                f" {fmt_s(r['t_eig'])} | {fmt_s(floor)} | {floor / one:.2f} |"
                f" {fmt_s(r['t_textbook'])} | {r['t_rep'] / r['t_textbook']:.2f} |"
            )
        out += ["", "The floor is what the eigenproblems alone cost: every exact replicate"
                " model needs the leading subspace of its q ny x q ny Schur complement and"
                " the eigenvalues and eigenvectors of its n_ref x n_ref A, 100 times, spread"
                " over the worker threads. Where the floor alone exceeds 3x one"
                " identification the 3x target cannot be met with exact replicate models."
                " The textbook fit is method.md section 1 as written (LQ of the real-stacked"
                " data matrix, SVD of L22, shift invariance, B and D by the stacked linear"
                " least squares), one thread: the single identification that target was"
                " set against, before the Gram path and the normal-equation B/D made one"
                " fit several times cheaper.", ""]
    if peers:
        out += render_peers(meta, cli, ratios, peers)
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    if args.sdypy_child:
        sdypy_child(args.sdypy_child)
        return 0
    tmp = None
    if args.workdir:
        workdir = Path(args.workdir)
        workdir.mkdir(parents=True, exist_ok=True)
    else:
        tmp = tempfile.TemporaryDirectory(prefix="automodal_e2e_")
        workdir = Path(tmp.name)
    meta = {
        "date": datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z"),
        "machine": f"{platform.machine()} {platform.processor() or platform.platform()}",
        "nproc": os.cpu_count(), "python": platform.python_version(), "blas": blas_line(),
        "git": git_state(), "repeat": args.repeat, "load_start": load_average(),
        "simulate": [], "dims": {}, "true": {}, "peak_method": peak_method(),
    }
    cli, ratios, peers, splits = {}, {}, {}, {}
    try:
        paths = {}
        for key in args.cases:
            path, cmd, true_f = simulate_case(key, workdir)
            paths[key] = path
            meta["simulate"].append(cmd)
            meta["true"][key] = true_f
            from automodal.io.frf_file import read_frf

            d = read_frf(str(path))
            meta["dims"][key] = d.frf.shape
        # children first: nothing of this process's later growth can reach them
        for key in args.cases:
            npz = None
            if key in PEER_CASES:
                npz = write_peer_input(key, paths[key], meta["true"][key], workdir)
            who = "automodal identify" + (" and sdypy-EMA, interleaved" if npz else "")
            print(f"[{time.strftime('%H:%M:%S')}] case {key}: {who}", flush=True)
            cli[key], peer = bench_case(key, paths[key], meta["true"][key], args.repeat, npz)
            r = cli[key]
            print(f"    automodal: median {r['wall']:.2f} s, peak {r['peak_mb']:.0f} MB,"
                  f" {r['matched']}/{r['n_true']} found, {r['extra']} extra", flush=True)
            if peer is not None:
                peers[key] = peer
                if "info" in peer:
                    print(f"    sdypy-EMA: median {peer['wall']:.2f} s,"
                          f" {peer['matched']}/{r['n_true']} found, {peer['extra']} extra;"
                          f" ratio {r['wall'] / peer['wall']:.2f}", flush=True)
        for key in [k for k in args.cases if k in RATIO_CASES]:
            print(f"[{time.strftime('%H:%M:%S')}] case {key}: replicates vs one identification",
                  flush=True)
            load = load_average()
            r = bench_replicates(paths[key], args.repeat)
            r["load"] = load
            if "split" in r:  # identified in sub-bands: the in-process time only
                splits[key] = r
                print(f"    identified in {r['split']} sub-bands: pipeline.identify"
                      f" {r['t_pipeline']:.2f} s; no one model to compare", flush=True)
                continue
            ratios[key] = r
            one = one_fit(r)
            print(f"    one {one:.3f} s, replicates {r['t_rep']:.3f} s"
                  f" -> ratio {r['t_rep'] / one:.2f}", flush=True)
        meta["load_end"] = load_average()
        meta["splits"] = splits
    finally:
        if tmp is not None:
            tmp.cleanup()
    text = render(meta, cli, ratios, peers)
    print()
    print(text)
    if args.out:
        Path(args.out).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
