"""Benchmark: output-only (ambient) identification, automodal against pyOMA2's SSI-cov with its
automatic clustering presets, in the same run.

Datasets
--------
* ``weimar``: the Weimar steel frame, setup 1 (``measurement_1.npy``, 61 440 x 6 at 256 Hz,
  columns 0-4; column 5 is excluded as in the data set's own setup file). Reference: the
  11 modes of ``merged_setups.npz``, a mean over 14 setups of pyOMA (v1) SSI-cov results. Its
  damping is itself uncertain (standard deviation 40-60 % of the mean for modes 1-3) and it
  was made with SSI-cov, the method family of pyOMA2. Needs ``../shared/realdata`` (or
  ``--realdata``); skipped when absent.
* simulated ambient tests of known systems (:func:`simulate_ambient`): independent white-noise
  forces at every DOF, acceleration at every DOF, Gaussian measurement noise of a given
  fraction of each channel's RMS, sampled at 128 Hz (twice the top mode or more):

  - ``chain5``: 5-DOF chain (``simulate.chain(5)``), Rayleigh damping 1 % (0.68-1 %), 2 % noise;
  - ``chain5-light``: the same chain with Rayleigh damping 0.2 % (0.14-0.2 %), 1 % noise;
  - ``grid3x4``: 3 x 4 grid of masses (12 DOFs), non-proportional damping 1 % (complex modes,
    0.52-1.5 %), 5 % noise.

  Duration: ``--decays`` (default 400) decay times ``1 / (zeta * omega)`` of the
  slowest-decaying mode, plus 30 decay times simulated first and thrown away (transient).
  400 is inside the 200-1000 usually asked of a record for damping estimates and keeps the
  longest record (``chain5-light``, 2.0 h, 900 000 samples) under a minute per run.
  The truth is :func:`automodal.core.simulate.exact_modes` of the continuous system: the
  simulation is exact in discrete time for forces held over each sample (zero-order hold),
  so the sampled response has exactly the continuous poles.

Tools
-----
* automodal (this worktree): ``TimeSeries(outputs=y, inputs=None, sample_rate=fs)``,
  ``automodal.identify(series, Settings(seed=0))``, whose input stage
  (``automodal.pipeline.input_stage``) runs the output-only first pass and the plan
  (decimation, max lag; timed with the rest); every physical mode counts. The plan is
  listed per dataset.
* pyOMA2 (``pip install pyOMA-2``; ``pip install -e '.[bench]'``): ``SingleSetup(y, fs)``,
  ``decimate_data(q)`` when the data allow it, ``SSI(method="cov", br, ordmax=100, step=2)``
  as in pyOMA2's clustering example, then each automatic clustering preset
  (``Clustering(name=p, quick=p)`` for p in ``--presets``, default Reynders, Neu, Kvaale,
  Dederichs, Magalhaes); every cluster it returns counts as a mode. Choices, applied the same
  way to every dataset: decimation factor ``q`` the largest with ``fs / (2 q) >= 2 f_top``
  (Weimar: q = 4, 64 Hz; simulations: q = 1); block rows ``br = 10 ceil(fs_dec / (10 f_1))``
  so that the 2 br covariance lags span at least two periods of the lowest mode (Weimar 60,
  simulations 30); ``ordmax = 100`` with step 2 (50 orders). Some presets pre-cluster with
  scikit-learn's k-means or Gaussian mixture without a seed, so NumPy's global generator is
  seeded with the repetition number before each pyOMA2 run.

Measures, per dataset, tool (and preset) and repetition: modes matched one-to-one to the
truth within 1 % in frequency (closest pairs first), per-mode damping ratio and its error
relative to the truth, extra modes (unmatched; for Weimar only those below 15 Hz count, the
reference ending at 13.9 Hz), and wall time (``time.perf_counter`` from the array in memory
to the list of modes; imports and data loading excluded). For pyOMA2 the SSI run and each
clustering are timed apart; a preset's time is the SSI time plus its clustering time. The
tools run interleaved (automodal, then pyOMA2, for each dataset, for each repetition), and
the tables give medians over ``--repeat`` repetitions.

Run ``python benchmarks/bench_oma.py --help`` for the options; ``--out FILE.md`` writes the
Markdown report too.
"""

from __future__ import annotations

import argparse
import datetime
import logging
import math
import os
import subprocess
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.signal import cont2discrete, lfilter

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import automodal  # noqa: E402
from automodal.core import simulate  # noqa: E402
from automodal.pipeline import input_stage  # noqa: E402
from automodal.timedata import TimeSeries  # noqa: E402

PRESETS = ("Reynders", "Neu", "Kvaale", "Dederichs", "Magalhaes")
MATCH_TOL = 0.01
WEIMAR_EXTRA_BELOW_HZ = 15.0
SIM_FS = 128.0


@dataclass
class Dataset:
    """One output-only record and the modes it should give."""

    name: str
    description: str
    y: np.ndarray
    fs: float
    f_true: np.ndarray
    zeta_true: np.ndarray
    zeta_std: np.ndarray | None = None
    extra_below_hz: float = math.inf
    quantity: str = "acceleration"


@dataclass
class Run:
    """What one tool (or one pyOMA2 preset) found on one dataset in one repetition."""

    f: np.ndarray
    zeta: np.ndarray
    seconds: float
    detail: dict = field(default_factory=dict)


# ---------------------------------------------------------------------------------------
# Data
# ---------------------------------------------------------------------------------------


def simulate_ambient(system: simulate.MechanicalSystem, fs: float, duration_s: float,
                     noise: float, seed: int, settle_s: float = 0.0) -> np.ndarray:
    """Accelerations at every DOF under independent white-noise forces at every DOF.

    The continuous model of :func:`automodal.core.simulate.state_space` is discretised with
    a zero-order hold and run in modal coordinates (one first-order recursion per state,
    :func:`scipy.signal.lfilter`). Unit-variance forces; then Gaussian noise of ``noise``
    times each channel's RMS is added. The first ``settle_s`` seconds are thrown away.

    Returns
    -------
    ndarray, (samples, n_dof)
    """
    n = system.n_dof
    A, B, C, D = simulate.state_space(system, range(n), range(n), quantity="acceleration")
    Ad, Bd, _, _, _ = cont2discrete((A, B, C, D), 1.0 / fs, method="zoh")
    rng = np.random.default_rng(seed)
    n_settle = int(round(settle_s * fs))
    n_keep = int(round(duration_s * fs))
    u = rng.standard_normal((n_settle + n_keep, n))
    mu, V = np.linalg.eig(Ad)
    g = np.linalg.solve(V, Bd @ u.T)  # modal inputs, (states, samples)
    z = np.empty_like(g)
    for i in range(mu.size):  # z[k] = mu z[k-1] + g[k-1]
        z[i] = lfilter([0.0, 1.0], [1.0, -mu[i]], g[i])
    x = (V @ z).real
    y = (C @ x + D @ u.T).T[n_settle:]
    rms = np.sqrt(np.mean(y**2, axis=0))
    return y + noise * rms * rng.standard_normal(y.shape)


def simulated_dataset(name: str, system: simulate.MechanicalSystem, noise: float,
                      decays: float, seed: int, label: str) -> Dataset:
    """A :func:`simulate_ambient` record ``decays`` decay times of its slowest mode long."""
    modes = simulate.exact_modes(system)
    tau = np.max(1.0 / (modes.damping_ratio * 2 * np.pi * modes.frequency_hz))
    y = simulate_ambient(system, SIM_FS, decays * tau, noise, seed, settle_s=30 * tau)
    desc = (f"{label}; {y.shape[1]} accelerations, white-noise forces at every DOF, "
            f"{100 * noise:g} % noise, {SIM_FS:g} Hz, {y.shape[0] / SIM_FS:.0f} s "
            f"({decays:g} x tau = {tau:.2f} s), {y.shape[0]} samples")
    return Dataset(name, desc, y, SIM_FS, modes.frequency_hz, modes.damping_ratio)


def simulated_datasets(decays: float, seed: int) -> list[Dataset]:
    """The three simulated ambient tests of the module docstring."""
    chain = simulate.chain(5)
    grid = simulate.grid(3, 4)
    return [
        simulated_dataset("chain5", simulate.damp(chain, "rayleigh", 0.01), 0.02, decays,
                          seed, "5-DOF chain, Rayleigh 1 %"),
        simulated_dataset("chain5-light", simulate.damp(chain, "rayleigh", 0.002), 0.01,
                          decays, seed + 1, "5-DOF chain, Rayleigh 0.2 %"),
        simulated_dataset("grid3x4", simulate.damp(grid, "nonproportional", 0.01), 0.05,
                          decays, seed + 2, "3x4 grid, non-proportional 1 %"),
    ]


def weimar_dataset(realdata: Path) -> Dataset | None:
    """Weimar setup 1 and its 14-setup reference, or None when the data are absent."""
    folder = realdata / "weimar_steel_frame"
    if not (folder / "measurement_1" / "measurement_1.npy").is_file():
        return None
    y = np.load(folder / "measurement_1" / "measurement_1.npy")[:, :5]
    ref = np.load(folder / "merged_setups.npz", allow_pickle=True)
    f = ref["self.mean_frequencies"].ravel()
    order = np.argsort(f)
    zeta = ref["self.mean_damping"].ravel()[order] / 100
    zeta_std = ref["self.std_damping"].ravel()[order] / 100
    desc = ("Weimar steel frame setup 1, columns 0-4 (3 LDV velocities, 2 accelerations), "
            "256 Hz, 240 s; reference: 14-setup SSI-cov mean (merged_setups.npz)")
    return Dataset("weimar", desc, y, 256.0, f[order], zeta, zeta_std,
                   extra_below_hz=WEIMAR_EXTRA_BELOW_HZ, quantity="velocity")


# ---------------------------------------------------------------------------------------
# Tools
# ---------------------------------------------------------------------------------------


def run_automodal(ds: Dataset) -> Run:
    """automodal from the array in memory to its physical modes."""
    ts = TimeSeries(outputs=ds.y, inputs=None, sample_rate=ds.fs,
                    output_names=[f"ch{i}" for i in range(ds.y.shape[1])],
                    attributes={"quantity": ds.quantity})
    settings = automodal.Settings(seed=0)
    t0 = time.perf_counter()
    data = input_stage(ts, settings)  # what automodal.identify(ts, settings) does first
    result = automodal.identify(data, settings)
    seconds = time.perf_counter() - t0
    modes = result.physical_modes
    info = data.attributes["time_analysis"]
    plan = (f"decimation {info['decimation']} ({info['analysed_sample_rate_hz']:g} Hz, band "
            f"{info['band_hz'][0]:.3g}-{info['band_hz'][1]:.3g} Hz), max lag "
            f"{info['nperseg']} samples = {info['max_lag_s']:.2f} s, references "
            f"{info['references']}")
    return Run(np.array([m.frequency_hz for m in modes]),
               np.array([m.damping_ratio for m in modes]), seconds, {"plan": plan})


def pyoma_choices(ds: Dataset) -> tuple[int, int]:
    """Decimation factor and block rows, by the rules of the module docstring."""
    q = max(1, int(ds.fs / (4 * ds.f_true.max())))
    br = 10 * math.ceil(ds.fs / q / (10 * ds.f_true.min()))
    return q, br


def run_pyoma(ds: Dataset, presets: tuple[str, ...], seed: int) -> dict[str, Run]:
    """pyOMA2 SSI-cov once, then each clustering preset; one Run per preset."""
    from pyoma2.algorithms.data.run_params import Clustering, SSIRunParams
    from pyoma2.algorithms.ssi import SSI
    from pyoma2.setup.single import SingleSetup

    q, br = pyoma_choices(ds)
    np.random.seed(seed)
    t0 = time.perf_counter()
    setup = SingleSetup(ds.y.copy(), fs=ds.fs)
    if q > 1:
        setup.decimate_data(q=q)
    ssi = SSI(name="ssicov", run_params=SSIRunParams(br=br, ordmax=100, step=2, method="cov"))
    ssi.add_clustering(*[Clustering(name=p, quick=p) for p in presets])
    setup.add_algorithms(ssi)
    setup.run_by_name("ssicov")
    t_ssi = time.perf_counter() - t0
    runs = {}
    for p in presets:
        t1 = time.perf_counter()
        try:
            ssi.run_clustering(p)
            res = ssi.result.clustering_results[p]
            f, zeta = np.asarray(res.Fn, float).ravel(), np.asarray(res.Xi, float).ravel()
            error = ""
        except Exception as exc:  # a preset that fails is reported, not fatal
            f, zeta, error = np.array([]), np.array([]), f"{type(exc).__name__}: {exc}"[:120]
        t_clus = time.perf_counter() - t1
        order = np.argsort(f)
        runs[p] = Run(f[order], zeta[order], t_ssi + t_clus,
                      {"ssi_s": t_ssi, "clustering_s": t_clus, "q": q, "br": br,
                       "error": error})
    return runs


# ---------------------------------------------------------------------------------------
# Scoring
# ---------------------------------------------------------------------------------------


def match(f_true: np.ndarray, f_found: np.ndarray, tol: float = MATCH_TOL) -> np.ndarray:
    """For each true mode the index of its found mode (-1: none), one-to-one, closest first."""
    out = np.full(f_true.size, -1)
    if f_found.size == 0:
        return out
    rel = np.abs(f_found[None, :] - f_true[:, None]) / f_true[:, None]
    used = np.zeros(f_found.size, bool)
    for flat in np.argsort(rel, axis=None, kind="stable"):
        i, j = np.unravel_index(flat, rel.shape)
        if rel[i, j] >= tol:
            break
        if out[i] < 0 and not used[j]:
            out[i], used[j] = j, True
    return out


@dataclass
class Score:
    """A Run scored against a Dataset."""

    found: int
    extra: int
    extra_hz: list[float]
    uncounted_hz: list[float]  # unmatched at or above the dataset's extra_below_hz
    f: np.ndarray  # per true mode, nan when missed
    zeta: np.ndarray
    seconds: float


def score(ds: Dataset, run: Run) -> Score:
    """Matched modes, their frequency and damping, and the extras that count."""
    idx = match(ds.f_true, run.f)
    hit = idx >= 0
    f = np.where(hit, run.f[idx], np.nan) if run.f.size else np.full(idx.size, np.nan)
    zeta = np.where(hit, run.zeta[idx], np.nan) if run.f.size else np.full(idx.size, np.nan)
    unmatched = np.setdiff1d(np.arange(run.f.size), idx[hit])
    extra = [float(run.f[j]) for j in unmatched if run.f[j] < ds.extra_below_hz]
    above = [float(run.f[j]) for j in unmatched if run.f[j] >= ds.extra_below_hz]
    return Score(int(hit.sum()), len(extra), extra, above, f, zeta, run.seconds)


# ---------------------------------------------------------------------------------------
# Report
# ---------------------------------------------------------------------------------------


def nanmedian(values: list[np.ndarray]) -> np.ndarray:
    """Element-wise median over repetitions, ignoring misses (nan when always missed)."""
    stack = np.array(values, float)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmedian(stack, axis=0)


def summary_rows(ds: Dataset, scores: dict[str, list[Score]]) -> list[str]:
    """One row per tool: modes found, extras, damping error summary, wall time."""
    rows = ["| tool | modes found (per rep) | extra modes (per rep) | median abs. damping "
            "error | max abs. damping error | wall time s (median; reps) |",
            "|---|---|---|---|---|---|"]
    for tool, reps in scores.items():
        zeta = nanmedian([s.zeta for s in reps])
        err = np.abs(zeta - ds.zeta_true) / ds.zeta_true
        err = err[np.isfinite(err)]
        med = f"{100 * np.median(err):.0f} %" if err.size else "-"
        mx = f"{100 * np.max(err):.0f} %" if err.size else "-"
        times = [s.seconds for s in reps]
        rows.append(
            f"| {tool} | {'/'.join(str(s.found) for s in reps)} of {ds.f_true.size} | "
            f"{'/'.join(str(s.extra) for s in reps)} | {med} | {mx} | "
            f"{np.median(times):.1f}; {', '.join(f'{t:.1f}' for t in times)} |")
    return rows


def mode_rows(ds: Dataset, scores: dict[str, list[Score]]) -> list[str]:
    """Per true mode: truth, then each tool's median frequency and damping, damping error."""
    ref = "reference" if ds.zeta_std is not None else "truth"
    head = f"| mode | {ref} f Hz | {ref} zeta % |"
    rule = "|---|---|---|"
    if ds.zeta_std is not None:
        head += " ref. std zeta % |"
        rule += "---|"
    for tool in scores:
        head += f" {tool} f | zeta % | err |"
        rule += "---|---|---|"
    rows = [head, rule]
    medians = {tool: (nanmedian([s.f for s in reps]), nanmedian([s.zeta for s in reps]))
               for tool, reps in scores.items()}
    for k in range(ds.f_true.size):
        row = f"| {k + 1} | {ds.f_true[k]:.4f} | {100 * ds.zeta_true[k]:.3f} |"
        if ds.zeta_std is not None:
            row += f" {100 * ds.zeta_std[k]:.3f} |"
        for f, zeta in medians.values():
            if np.isfinite(f[k]):
                err = 100 * (zeta[k] - ds.zeta_true[k]) / ds.zeta_true[k]
                row += f" {f[k]:.4f} | {100 * zeta[k]:.3f} | {err:+.0f} % |"
            else:
                row += " - | - | - |"
        rows.append(row)
    return rows


def listed(hz: list[float], at_most: int = 30) -> str:
    """Frequencies as text, the first ``at_most``."""
    text = ", ".join(f"{f:.2f}" for f in sorted(hz)[:at_most])
    return (text + (" ..." if len(hz) > at_most else "")) or "none"


def extra_rows(ds: Dataset, scores: dict[str, list[Score]]) -> list[str]:
    """The extra modes of each tool's first repetition (and the uncounted ones)."""
    rows = []
    for tool, reps in scores.items():
        row = f"- {tool}: {listed(reps[0].extra_hz)}"
        if ds.extra_below_hz < math.inf:
            row += f"; not counted (>= {ds.extra_below_hz:g} Hz): {listed(reps[0].uncounted_hz)}"
        rows.append(row)
    return rows


def git_head() -> str:
    """The worktree's commit (and '+dirty' when it has changes)."""
    def git(*args: str) -> str:
        return subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True,
                              text=True, check=False).stdout.strip()
    return git("rev-parse", "HEAD") + ("+dirty" if git("status", "--porcelain") else "")


def report(datasets: list[Dataset], all_scores: dict[str, dict[str, list[Score]]],
           details: dict[str, dict], args: argparse.Namespace) -> str:
    """The Markdown report."""
    from importlib.metadata import version

    lines = ["# Output-only benchmark: automodal vs pyOMA2 SSI-cov + clustering presets",
             "",
             f"Generated {datetime.datetime.now():%Y-%m-%d %H:%M} by "
             f"`python benchmarks/bench_oma.py {' '.join(sys.argv[1:])}`; automodal commit "
             f"`{git_head()}`; pyOMA-2 {version('pyOMA-2')}; {args.repeat} repetitions, "
             f"interleaved; BLAS threads: {args.blas_threads or 'library default'}; "
             f"load average at the end {os.getloadavg()[0]:.2f} (2 shared cores: times "
             "are inflated by other users' load).",
             ""]
    for ds in datasets:
        d = details[ds.name]
        lines += [f"## {ds.name}", "", ds.description + ".",
                  f"pyOMA2: decimation q = {d['q']}, br = {d['br']}, ordmax = 100, step 2; "
                  f"SSI run median {d['ssi_s']:.1f} s (a preset's time includes it).", "",
                  f"automodal's plan (first repetition): {d['plan']}.", ""]
        if ds.extra_below_hz < math.inf:
            lines += [f"Extra modes counted below {ds.extra_below_hz:g} Hz only.", ""]
        lines += summary_rows(ds, all_scores[ds.name]) + [""]
        lines += mode_rows(ds, all_scores[ds.name]) + [""]
        lines += ["Extra modes (first repetition, Hz):", ""] + extra_rows(ds, all_scores[ds.name])
        lines += [""]
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------------------
# Main
# ---------------------------------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=3, help="repetitions (default 3)")
    parser.add_argument("--datasets", default="weimar,chain5,chain5-light,grid3x4",
                        help="comma-separated subset")
    parser.add_argument("--presets", default=",".join(PRESETS),
                        help="pyOMA2 clustering presets, comma-separated")
    parser.add_argument("--decays", type=float, default=400.0,
                        help="simulated record length in decay times of the slowest mode")
    parser.add_argument("--seed", type=int, default=1, help="simulation seed")
    parser.add_argument("--realdata", type=Path, default=ROOT.parent / "shared" / "realdata")
    parser.add_argument("--blas-threads", type=int, default=1,
                        help="BLAS threads for both tools (0: library default)")
    parser.add_argument("--out", type=Path, help="also write the Markdown report here")
    args = parser.parse_args(argv)
    wanted = args.datasets.split(",")
    presets = tuple(p for p in args.presets.split(",") if p)

    logging.disable(logging.WARNING)  # pyOMA2 logs every step
    warnings.filterwarnings("ignore", category=FutureWarning)
    os.environ.setdefault("TQDM_DISABLE", "1")

    datasets = []
    if "weimar" in wanted:
        ds = weimar_dataset(args.realdata)
        if ds is None:
            print(f"weimar: no data under {args.realdata}; skipped", file=sys.stderr)
        else:
            datasets.append(ds)
    datasets += [d for d in simulated_datasets(args.decays, args.seed) if d.name in wanted]

    from threadpoolctl import threadpool_limits
    limits = threadpool_limits(args.blas_threads) if args.blas_threads else None

    all_scores = {ds.name: {"automodal": [], **{f"pyOMA2 {p}": [] for p in presets}}
                  for ds in datasets}
    ssi_times: dict[str, list[float]] = {ds.name: [] for ds in datasets}
    details: dict[str, dict] = {}
    for rep in range(args.repeat):
        for ds in datasets:
            run = run_automodal(ds)
            all_scores[ds.name]["automodal"].append(score(ds, run))
            print(f"rep {rep} {ds.name} automodal: {run.seconds:.1f} s", file=sys.stderr)
            runs = run_pyoma(ds, presets, seed=rep)
            for p, r in runs.items():
                all_scores[ds.name][f"pyOMA2 {p}"].append(score(ds, r))
                if r.detail["error"]:
                    print(f"  pyOMA2 {p} failed: {r.detail['error']}", file=sys.stderr)
            first = next(iter(runs.values())).detail
            ssi_times[ds.name].append(first["ssi_s"])
            details[ds.name] = {"q": first["q"], "br": first["br"],
                                **details.get(ds.name, {"plan": run.detail["plan"]})}
            print(f"rep {rep} {ds.name} pyOMA2: SSI {first['ssi_s']:.1f} s, "
                  + ", ".join(f"{p} {r.detail['clustering_s']:.1f} s" for p, r in runs.items()),
                  file=sys.stderr)
    if limits is not None:
        limits.restore_original_limits()
    for name, times in ssi_times.items():
        details[name]["ssi_s"] = float(np.median(times))

    text = report(datasets, all_scores, details, args)
    print(text)
    if args.out:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
