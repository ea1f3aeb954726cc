"""Benchmark: one subspace identification on the QR path against the Gram (fast) path.

For a grid of sizes (lines N, outputs ny, inputs nu, model order n) the script times

* the observability step alone, ``subspace.observability(basis, H, n, method)`` with
  ``method="qr"`` (LQ projection + SVD of L22) and ``method="gram"`` (Gram matrix + Schur
  complement + eigh, however the package forms the Gram matrix for the chosen row basis),
  with the row basis built beforehand and shared;
* the whole ``identify(..., estimate_bd_=False)`` on each path (row basis included);

and compares the two observability subspaces by their largest principal angle. A second
table times the batched bootstrap: ``gram_sums`` with a (100, N) weight matrix followed by
100 Schur complements and eigh, against 100 weighted QR projections and SVDs.

The data are the noisy FRFs of a lightly damped structure: a 10 x 10 grid of masses
(100 DOFs, Rayleigh damping 1 %), accelerance, 1 % proportional noise, analysed in a band
that holds its lowest 40 modes. Outputs are spread evenly over the grid; inputs are three
fixed interior DOFs.

Run ``python benchmarks/bench_subspace.py --help`` for the options; see README.md beside it.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import os
import platform
import sys
import time

import numpy as np
import scipy
import scipy.linalg as sla

from automodal.core import bilinear, bootstrap, subspace
from automodal.core import simulate as sim

# ---------------------------------------------------------------------------- settings

FULL_GRID = {
    "lines": [1000, 2000, 4000, 8000],
    "outputs": [1, 6, 20, 60],
    "inputs": [1, 3],
    "orders": [20, 80, 200],
}
QUICK_GRID = {
    "lines": [1000, 2000],
    "outputs": [1, 20],
    "inputs": [1, 3],
    "orders": [20, 40],
}
# (N, ny, nu, n) of the bootstrap comparison
FULL_BOOT = [(2000, 1, 1, 80), (4000, 6, 3, 80), (4000, 20, 3, 200), (8000, 60, 3, 200)]
QUICK_BOOT = [(1000, 6, 1, 20), (2000, 20, 3, 40)]

GRID_SHAPE = (10, 10)  # masses of the test structure
MODES_IN_BAND = 40  # the band ends 2 % above the 40th natural frequency
INPUT_DOFS = (11, 47, 83)  # 0-based force DOFs (interior, away from symmetry lines)
NOISE = 0.01
ZETA = 0.01
SEED = 20240601


# ---------------------------------------------------------------------------- helpers


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(
        description="Time the QR path against the Gram path of automodal's subspace "
        "identification and print Markdown tables."
    )
    ap.add_argument("--quick", action="store_true",
                    help="a small subset (N <= 2000, ny in {1, 20}, n in {20, 40}); < 1 min")
    ap.add_argument("--repeat", type=int, default=3,
                    help="runs per measurement; the minimum is reported (default 3)")
    ap.add_argument("--budget", type=float, default=8.0,
                    help="seconds per measurement after which no further repeat is started "
                    "(at least one run always; 'inf' to always do --repeat runs; default 8)")
    ap.add_argument("--out", metavar="FILE.md", help="also write the tables to this file")
    ap.add_argument("--lines", type=int, nargs="+", help="override the grid's N values")
    ap.add_argument("--outputs", type=int, nargs="+", help="override the grid's ny values")
    ap.add_argument("--inputs", type=int, nargs="+", help="override the grid's nu values")
    ap.add_argument("--orders", type=int, nargs="+", help="override the grid's n values")
    ap.add_argument("--replicates", type=int, default=100,
                    help="bootstrap replicates in the batched comparison (default 100)")
    ap.add_argument("--qr-sample", type=int, default=None,
                    help="weighted QR replicates actually run per bootstrap size; the "
                    "time for all replicates is extrapolated (default 5, quick 3)")
    ap.add_argument("--no-bootstrap", action="store_true", help="skip the bootstrap table")
    ap.add_argument("--blas-threads", type=int, default=None,
                    help="limit BLAS threads with threadpoolctl for this run (default: "
                    "leave the library default alone)")
    args = ap.parse_args(argv)
    if args.repeat < 1:
        ap.error("--repeat must be >= 1")
    if args.qr_sample is None:
        args.qr_sample = 3 if args.quick else 5
    return args


def best_of(fn, repeat: int, budget: float):
    """Minimum wall time of up to ``repeat`` calls of ``fn``; stops starting new calls once
    ``budget`` seconds have been spent. Returns (best seconds, runs done, last result)."""
    times = []
    result = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
        if sum(times) >= budget:
            break
    return min(times), len(times), result


def blas_summary() -> str:
    """One line: the BLAS numpy was built with and what runs now (threads, kernel)."""
    parts = []
    try:
        cfg = np.show_config(mode="dicts")["Build Dependencies"]["blas"]
        parts.append(f"{cfg.get('name')} {cfg.get('version')}")
        extra = cfg.get("openblas configuration")
        if extra:
            parts.append(f"({' '.join(extra.split())})")
    except Exception:  # older numpy: no dict mode
        parts.append("numpy BLAS (config unavailable)")
    try:
        import threadpoolctl

        seen = set()
        for info in threadpoolctl.threadpool_info():
            if info.get("user_api") != "blas":
                continue
            key = (info.get("internal_api"), info.get("version"), info.get("num_threads"),
                   info.get("architecture"))
            if key not in seen:
                seen.add(key)
                parts.append(
                    f"runtime: {info.get('internal_api')} {info.get('version')}, "
                    f"{info.get('num_threads')} threads, kernel {info.get('architecture')}"
                )
    except ImportError:
        pass
    return "; ".join(parts)


def code_version() -> str:
    """Commit of the repository holding automodal, and whether subspace.py differs from it."""
    import hashlib
    import subprocess

    path = os.path.abspath(subspace.__file__)
    with open(path, "rb") as fh:
        digest = hashlib.sha256(fh.read()).hexdigest()[:12]
    where = os.path.dirname(path)
    try:
        head = subprocess.run(["git", "-C", where, "rev-parse", "--short", "HEAD"],
                              capture_output=True, text=True, timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "-C", where, "status", "--porcelain", path],
                               capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        head, dirty = "", ""
    state = (" (modified)" if dirty else "") if head else ""
    return f"automodal commit {head or 'unknown'}{state}, subspace.py sha256 {digest}"


def machine_summary() -> str:
    cpu = platform.processor() or platform.machine()
    with contextlib.suppress(OSError):
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    return (f"nproc {os.cpu_count()}, {cpu}; Python {platform.python_version()}, "
            f"numpy {np.__version__}, scipy {scipy.__version__}")


def fmt_s(seconds: float, runs: int, wanted: int) -> str:
    """Seconds with 3 significant digits; a '*' when fewer runs than wanted were done."""
    if seconds >= 100:
        txt = f"{seconds:.0f}"
    elif seconds >= 10:
        txt = f"{seconds:.1f}"
    elif seconds >= 1:
        txt = f"{seconds:.2f}"
    else:
        txt = f"{seconds:.3f}"
    return txt + ("*" if runs < wanted else "")


def markdown(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---:" for _ in header) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


# ---------------------------------------------------------------------------- test data


class TestStructure:
    """The damped grid and its noisy FRF at all DOFs for the input DOFs, per N."""

    def __init__(self) -> None:
        self.system = sim.damp(sim.grid(*GRID_SHAPE), "rayleigh", zeta=ZETA)
        fn = sim.natural_frequencies_hz(self.system)
        self.f_max = 1.02 * fn[MODES_IN_BAND - 1]
        self.n_dof = self.system.n_dof
        self._cache: dict[int, tuple[np.ndarray, np.ndarray, float]] = {}

    def data(self, n_lines: int) -> tuple[np.ndarray, np.ndarray, float]:
        """(z, H_all, T): unit-circle points, FRF (N, n_dof, len(INPUT_DOFS)), bilinear T."""
        if n_lines not in self._cache:
            f = sim.frequency_lines(self.f_max, n_lines)
            clean = sim.frf(self.system, f, None, list(INPUT_DOFS), "acceleration")
            noisy = sim.add_noise(clean, NOISE, np.random.default_rng(SEED + n_lines))
            omega = 2.0 * np.pi * f
            T = bilinear.default_scale(omega[0], omega[-1])
            self._cache[n_lines] = (bilinear.to_unit_circle(omega, T), noisy, T)
        return self._cache[n_lines]

    def outputs(self, ny: int) -> np.ndarray:
        """``ny`` output DOFs spread evenly over the grid (DOF 0, a corner, for ny = 1)."""
        if ny > self.n_dof:
            raise ValueError(f"the structure has only {self.n_dof} DOFs")
        idx = np.unique(np.round(np.linspace(0, self.n_dof - 1, ny)).astype(int))
        if idx.size != ny:
            raise ValueError(f"cannot spread {ny} outputs over {self.n_dof} DOFs")
        return idx

    def frf(self, n_lines: int, ny: int, nu: int) -> tuple[np.ndarray, np.ndarray, float]:
        if nu > len(INPUT_DOFS):
            raise ValueError(f"at most {len(INPUT_DOFS)} inputs")
        z, H_all, T = self.data(n_lines)
        H = np.ascontiguousarray(H_all[:, self.outputs(ny), :nu])
        return z, H, T


def fits(n_lines: int, ny: int, nu: int, q: int) -> bool:
    """Whether the real-stacked data matrix has at least as many columns as rows."""
    return 2 * n_lines * nu >= q * (nu + ny)


# ---------------------------------------------------------------------------- main grid


def time_one_size(data: TestStructure, n_lines, ny, nu, n, args):
    q = subspace.block_rows(n, ny)
    z, H, T = data.frf(n_lines, ny, nu)
    # the observability step sees the data as identify() does: channel-scaled
    Hs = H / subspace.channel_scales(H)[None, :, None]
    t0 = time.perf_counter()
    basis = subspace.row_basis(z, q)
    t_basis = time.perf_counter() - t0

    def obs(method):
        return subspace.observability(basis, Hs, n, method)

    def ident(method):
        return subspace.identify(z, H, n, T, method=method, estimate_bd_=False)

    rep, bud = args.repeat, args.budget
    t_oq, r_oq, (O_qr, _, _) = best_of(lambda: obs("qr"), rep, bud)
    t_og, r_og, (O_gr, sv_gr, _) = best_of(lambda: obs("gram"), rep, bud)
    t_iq, r_iq, _ = best_of(lambda: ident("qr"), rep, bud)
    t_ig, r_ig, _ = best_of(lambda: ident("gram"), rep, bud)
    angle = float(np.max(sla.subspace_angles(O_qr, O_gr)))
    auto = "gram" if subspace.gram_resolves(sv_gr) else "qr"
    row = [
        str(n_lines), str(ny), str(nu), str(n), str(q),
        "mono" if basis.monomial else "orth",
        fmt_s(t_oq, r_oq, rep), fmt_s(t_og, r_og, rep), f"{t_oq / t_og:.2f}",
        fmt_s(t_iq, r_iq, rep), fmt_s(t_ig, r_ig, rep), f"{t_iq / t_ig:.2f}",
        f"{angle:.1e}", auto, fmt_s(t_basis, 1, 1),
    ]
    return row, dict(obs_speedup=t_oq / t_og, id_speedup=t_iq / t_ig, angle=angle,
                     auto=auto, key=(n_lines, ny, nu, n))


MAIN_HEADER = [
    "N", "ny", "nu", "n", "q", "basis",
    "QR obs s", "Gram obs s", "obs speed-up",
    "QR identify s", "Gram identify s", "identify speed-up",
    "max angle (rad)", "auto uses", "row basis s",
]


def run_grid(data: TestStructure, grid: dict, args):
    rows, stats, skipped = [], [], []
    for n_lines in grid["lines"]:
        for ny in grid["outputs"]:
            for nu in grid["inputs"]:
                for n in grid["orders"]:
                    q = subspace.block_rows(n, ny)
                    if not fits(n_lines, ny, nu, q):
                        skipped.append((n_lines, ny, nu, n, q))
                        log(f"skip N={n_lines} ny={ny} nu={nu} n={n}: q={q} does not fit")
                        continue
                    t0 = time.perf_counter()
                    row, st = time_one_size(data, n_lines, ny, nu, n, args)
                    rows.append(row)
                    stats.append(st)
                    log(" | ".join(row) + f"   [{time.perf_counter() - t0:.1f} s]")
    return rows, stats, skipped


# ---------------------------------------------------------------------------- bootstrap


BOOT_HEADER = [
    "N", "ny", "nu", "n", "q", "basis",
    "gram_sums (B x N) s", "B x (Schur + eigh) s", "Gram total s",
    "QR s / replicate", "QR B replicates s", "speed-up", "max angle (rad)",
]


def time_bootstrap(data: TestStructure, n_lines, ny, nu, n, args):
    B = args.replicates
    q = subspace.block_rows(n, ny)
    z, H, _ = data.frf(n_lines, ny, nu)
    Hs = H / subspace.channel_scales(H)[None, :, None]
    basis = subspace.row_basis(z, q)
    weights = bootstrap.line_weights(n_lines, B, np.random.default_rng(SEED))

    def gram_all():
        sums = subspace.gram_sums(basis, Hs, weights)
        t_mid = time.perf_counter()
        obs = [subspace.observability_from_schur(subspace.schur_complement(sums, b), n)[0]
               for b in range(B)]
        return t_mid, obs

    # the Gram side runs once per repeat as a whole; split its time at the sums
    best = None
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        t_mid, obs_gram = gram_all()
        t1 = time.perf_counter()
        if best is None or t1 - t0 < best[0] + best[1]:
            best = (t_mid - t0, t1 - t_mid)
        if t1 - t0 >= args.budget:
            break
    t_sums, t_schur = best

    k = min(args.qr_sample, B)
    t_qr, angles = [], []
    for b in range(k):
        t0 = time.perf_counter()
        l22 = subspace.projected_output_qr(basis, Hs, weights[b])
        O_qr, _ = subspace.observability_from_l22(l22, n)
        t_qr.append(time.perf_counter() - t0)
        angles.append(float(np.max(sla.subspace_angles(O_qr, obs_gram[b]))))
    per_rep = float(np.mean(t_qr))
    qr_total = per_rep * B
    label = fmt_s(qr_total, 1, 1) + ("" if k == B else f" (from {k})")
    gram_total = t_sums + t_schur
    row = [
        str(n_lines), str(ny), str(nu), str(n), str(q),
        "mono" if basis.monomial else "orth",
        fmt_s(t_sums, 1, 1), fmt_s(t_schur, 1, 1), fmt_s(gram_total, 1, 1),
        fmt_s(per_rep, 1, 1), label, f"{qr_total / gram_total:.1f}", f"{max(angles):.1e}",
    ]
    return row


def run_bootstrap(data: TestStructure, sizes, args):
    rows = []
    for n_lines, ny, nu, n in sizes:
        q = subspace.block_rows(n, ny)
        if not fits(n_lines, ny, nu, q):
            log(f"bootstrap: skip N={n_lines} ny={ny} nu={nu} n={n}")
            continue
        t0 = time.perf_counter()
        row = time_bootstrap(data, n_lines, ny, nu, n, args)
        rows.append(row)
        log("boot | " + " | ".join(row) + f"   [{time.perf_counter() - t0:.1f} s]")
    return rows


# ---------------------------------------------------------------------------- report


def summary_lines(stats) -> list[str]:
    if not stats:
        return []
    obs = np.array([s["obs_speedup"] for s in stats])
    idn = np.array([s["id_speedup"] for s in stats])
    ang = np.array([s["angle"] for s in stats])
    worst = stats[int(np.argmin(obs))]["key"]
    best = stats[int(np.argmax(obs))]["key"]
    worst_ang = stats[int(np.argmax(ang))]["key"]
    fallback = sum(s["auto"] == "qr" for s in stats)
    kept = [s["angle"] for s in stats if s["auto"] == "gram"]
    gram_ang = max(kept) if kept else float("nan")
    return [
        f"- observability step, QR/Gram: median {np.median(obs):.2f}x, "
        f"best {obs.max():.2f}x at (N, ny, nu, n) = {best}, worst {obs.min():.2f}x at {worst}; "
        f"Gram faster in {int(np.sum(obs > 1))} of {obs.size} sizes",
        f"- whole identify, QR/Gram: median {np.median(idn):.2f}x, "
        f"range {idn.min():.2f}x .. {idn.max():.2f}x",
        f"- largest principal angle between the two subspaces: {ang.max():.1e} rad at "
        f"{worst_ang}; median {np.median(ang):.1e} rad; largest where method='auto' keeps "
        f"the Gram path: {gram_ang:.1e} rad",
        f"- sizes where method='auto' would fall back to QR (Gram eigenvalue ratio below "
        f"GRAM_MIN_EIG_RATIO): {fallback} of {len(stats)}",
    ]


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    grid = dict(QUICK_GRID if args.quick else FULL_GRID)
    for key in ("lines", "outputs", "inputs", "orders"):
        if getattr(args, key):
            grid[key] = getattr(args, key)
    boot_sizes = QUICK_BOOT if args.quick else FULL_BOOT

    limiter = contextlib.nullcontext()
    if args.blas_threads is not None:
        import threadpoolctl

        limiter = threadpoolctl.threadpool_limits(limits=args.blas_threads, user_api="blas")

    version = code_version()  # read before timing: the code must not change under us
    load_start = os.getloadavg()
    start = time.perf_counter()
    with limiter:
        data = TestStructure()
        # warm-up: first BLAS/LAPACK calls start threads and load kernels
        z, H, T = data.frf(1000, 6, 1)
        subspace.identify(z, H, 20, T, method="qr", estimate_bd_=False)
        subspace.identify(z, H, 20, T, method="gram", estimate_bd_=False)
        blas = blas_summary()
        rows, stats, skipped = run_grid(data, grid, args)
        boot_rows = [] if args.no_bootstrap else run_bootstrap(data, boot_sizes, args)
    elapsed = time.perf_counter() - start
    load_end = os.getloadavg()

    out = []
    out.append("## Observability step and one identification, QR path vs Gram path")
    out.append("")
    out.append(
        f"Data: {GRID_SHAPE[0]}x{GRID_SHAPE[1]} grid ({data.n_dof} DOFs), Rayleigh damping "
        f"{ZETA:.0%}, accelerance, {NOISE:.0%} proportional noise, band 0-{data.f_max:.1f} Hz "
        f"({MODES_IN_BAND} modes). Times: minimum of up to {args.repeat} runs "
        f"(time.perf_counter); '*' = fewer runs because one run exceeded the "
        f"{args.budget:g} s budget. Speed-up = QR time / Gram time."
    )
    out.append("")
    out.append(markdown(MAIN_HEADER, rows))
    out.append("")
    notes = summary_lines(stats)
    siso_q = [int(r[4]) for r in rows if r[1] == "1"]
    if siso_q:
        notes.append(f"- ny = 1 uses q = n + 1 block rows (up to {max(siso_q)} here): the QR "
                     "path then factors a q(nu+1) x 2 N nu matrix; timed anyway")
    if skipped:
        notes.append("- skipped (2 N nu < q (nu + ny)): " + ", ".join(
            f"N={a} ny={b} nu={c} n={d} (q={e})" for a, b, c, d, e in skipped))
    else:
        notes.append("- no size was skipped: every one satisfies 2 N nu >= q (nu + ny)")
    out.extend(notes)
    if boot_rows:
        out.append("")
        out.append(f"## Batched bootstrap, {args.replicates} replicates")
        out.append("")
        out.append(
            f"Gram: one gram_sums call with a ({args.replicates}, N) weight matrix, then "
            f"{args.replicates} Schur complements + eigh (minimum of up to {args.repeat} "
            f"runs). QR: weighted projected_output_qr + SVD per replicate; "
            f"'(from k)' = mean of k replicates times {args.replicates}. Max angle: between "
            f"the QR and Gram subspaces of the replicates run on both paths."
        )
        out.append("")
        out.append(markdown(BOOT_HEADER, boot_rows))
    out.append("")
    out.append(f"Run: {datetime.datetime.now().isoformat(timespec='seconds')}; "
               f"{machine_summary()}")
    out.append(f"BLAS: {blas}")
    out.append(f"Code: {version}")
    cmd = "python benchmarks/bench_subspace.py " + " ".join(
        sys.argv[1:] if argv is None else argv)
    out.append(f"Command: `{cmd.strip()}`; total wall time {elapsed:.0f} s")
    out.append(
        f"Load average (1, 5, 15 min) at start {', '.join(f'{x:.2f}' for x in load_start)}; "
        f"at end {', '.join(f'{x:.2f}' for x in load_end)} (other processes on the machine "
        f"distort the times; above about {os.cpu_count()} the numbers are suspect)"
    )
    text = "\n".join(out) + "\n"
    print(text)
    if args.out:
        with open(args.out, "w") as fh:
            fh.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
