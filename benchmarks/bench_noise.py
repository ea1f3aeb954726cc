"""How well the noise model (`automodal/core/noise.py`) finds the true noise on family FRFs.

The systems and their noise come from the project's family generator
(`shared/eval/family.py`: `make_system` and `measure`, which returns the TRUE noise std of
every line and FRF entry). They are made in memory, exactly as `family.py make DIR --n N
--seed S` makes them (same random draws), except that a system whose draw fails in the
generator (a dense grid asked for more sensors than it has DOFs) is skipped and counted.

Constants of `noise.py` were chosen on seeds 101 and 102 (`--seeds 101,102`); the stored
results are measured on seeds 201 and 202, which no constant saw.

Per noise kind and source, the table gives the distribution over FRF entries (one output,
one input) of the ratio ``RMS_k est_std / RMS_k true_std`` (10th, 50th, 90th percentile,
and the share of entries in [0.8, 1.25]), and the per-line agreement: the median over
entries of the median over lines of ``|log(est_std_k / true_std_k)|`` shown as a factor
``exp(.)`` (1.10 means a typical line is off by 10 %), over all lines and over each entry's 5 %
strongest lines (``at peaks``: the resonances).

Sources: ``records`` (plain averages: R = 8 records ``H + sqrt(R) sig e_r``, FRF = their mean,
made here from the additive and proportional systems), ``ratio records`` (the h1 files'
single-input ``/records/frf``, FRF = H1), ``coherence, n_d known`` (``n_averages`` = the
number of records R, as an attribute would give it), ``coherence, n_d calibrated`` (nothing
tells n_d: calibrated on the data-alone estimate, what `estimate_noise` does for the h1 files
with several inputs), ``data`` (the FRF alone), and ``auto`` (`estimate_noise` on what the file
holds).

    python benchmarks/bench_noise.py --seeds 201,202 --n 48 --out benchmarks/results_noise.md
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from automodal.core import noise

FAMILY = Path(__file__).resolve().parents[2] / "shared" / "eval" / "family.py"
KINDS = ["chain", "grid", "dense"]
NOISE_KINDS = ["additive", "proportional", "h1"]
N_RECORDS = 8


def load_family(path: Path):
    """Import family.py as a module."""
    spec = importlib.util.spec_from_file_location("family", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules["family"] = mod
    spec.loader.exec_module(mod)
    return mod


def systems(fam, seed: int, n: int):
    """The systems `family.py make --seed seed --n n` draws; (system or None, index)."""
    rng = np.random.default_rng(seed)
    for i in range(n):
        try:
            yield fam.make_system(i, rng, KINDS, NOISE_KINDS), i
        except ValueError:
            yield None, i


def entry_stats(
    est_var: np.ndarray, true_std: np.ndarray, frf: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per entry: RMS-std ratio, median over lines of |log(est/true)|, and that median over
    the entry's 5 % strongest lines (the resonance peaks)."""
    est = np.sqrt(est_var)
    ratio = np.sqrt(np.mean(est_var, axis=0)) / np.sqrt(np.mean(true_std**2, axis=0))
    with np.errstate(divide="ignore", invalid="ignore"):
        dl = np.abs(np.log(est / true_std))
    dev = np.median(dl, axis=0)
    k = max(1, frf.shape[0] // 20)
    top = np.argsort(np.abs(frf), axis=0)[-k:]
    dev_peak = np.median(np.take_along_axis(dl, top, axis=0), axis=0)
    return ratio.ravel(), dev.ravel(), dev_peak.ravel()


def run(seeds: list[int], n: int, max_lines: int | None) -> tuple[dict, dict]:
    fam = load_family(FAMILY)
    acc: dict = defaultdict(
        lambda: {"ratio": [], "dev": [], "peak": [], "files": 0, "secs": 0.0}
    )
    info = {"skipped": 0, "files": 0, "by_kind": defaultdict(int), "nd_calibrated": []}
    for seed in seeds:
        for s, _ in systems(fam, seed, n):
            if s is None:
                info["skipped"] += 1
                continue
            if max_lines and s.n_freq > max_lines:
                s.n_freq = max_lines
            _f, H, sig, coh, rec = fam.measure(s)
            info["files"] += 1
            info["by_kind"][s.noise_kind] += 1
            nu = H.shape[2]
            kind = (
                s.noise_kind
                if s.noise_kind != "h1"
                else f"h1 ({'1 input' if nu == 1 else f'{nu} inputs'})"
            )

            def add(
                source: str, var: np.ndarray, secs: float, sig=sig, H=H, kind=kind
            ) -> None:
                r, d, dp = entry_stats(var, sig, H)
                cell = acc[(kind, source)]
                cell["ratio"].extend(r.tolist())
                cell["dev"].extend(d.tolist())
                cell["peak"].extend(dp.tolist())
                cell["files"] += 1
                cell["secs"] += secs

            t0 = time.perf_counter()
            v, _, _ = noise.data_variance(H)
            add("data", v, time.perf_counter() - t0)
            if s.noise_kind == "h1":
                t0 = time.perf_counter()
                add(
                    "coherence, n_d known",
                    noise.coherence_variance(H, coh, s.records),
                    time.perf_counter() - t0,
                )
                if (
                    nu > 1
                ):  # the same without the inputs' chance-correlation factor (n_d - 1) / (n_d - nu)
                    v0 = (
                        noise.coherence_variance(H, coh, s.records)
                        * (s.records - nu)
                        / (s.records - 1)
                    )
                    add("coherence, n_d known, no Wishart factor", v0, 0.0)
                t0 = time.perf_counter()
                est = noise.estimate_noise(H, coherence=coh)
                add("coherence, n_d calibrated", est.variance, time.perf_counter() - t0)
                info["nd_calibrated"].append((s.records, est.n_averages))
                if rec is not None:
                    t0 = time.perf_counter()
                    add(
                        "ratio records",
                        noise.ratio_records_variance(rec, H),
                        time.perf_counter() - t0,
                    )
                t0 = time.perf_counter()
                est = noise.estimate_noise(H, coherence=coh, records=rec)
                add(f"auto -> {est.source}", est.variance, time.perf_counter() - t0)
            else:
                rng = np.random.default_rng(s.seed + 1)
                e = rng.standard_normal(
                    (N_RECORDS, *H.shape)
                ) + 1j * rng.standard_normal((N_RECORDS, *H.shape))
                recs = H[None] + np.sqrt(N_RECORDS) * sig[None] * e / np.sqrt(2)
                # the file's own noise draw cannot be undone, so the records are made around H
                # (the noisy FRF) as if H were exact; the truth is still sig
                t0 = time.perf_counter()
                add("records", noise.records_variance(recs), time.perf_counter() - t0)
                t0 = time.perf_counter()
                est = noise.estimate_noise(H)
                add(f"auto -> {est.source}", est.variance, time.perf_counter() - t0)
    return acc, info


def table(acc: dict) -> str:
    kinds = [
        "additive",
        "proportional",
        "h1 (1 input)",
        "h1 (2 inputs)",
        "h1 (3 inputs)",
    ]
    order = [
        "records",
        "ratio records",
        "coherence, n_d known",
        "coherence, n_d known, no Wishart factor",
        "coherence, n_d calibrated",
        "data",
    ]
    rows = [
        "| noise kind | source | entries (files) | ratio p10 | ratio median | ratio p90 | in "
        "[0.8, 1.25] | per-line factor | at peaks | s/file |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for k in kinds:
        srcs = [s for s in order if (k, s) in acc] + sorted(
            s for (kk, s) in acc if kk == k and s.startswith("auto")
        )
        for src in srcs:
            c = acc[(k, src)]
            r = np.asarray(c["ratio"])
            d = np.asarray(c["dev"])
            dp = np.asarray(c["peak"])
            p10, p50, p90 = np.percentile(r, [10, 50, 90])
            inside = np.mean((r >= 0.8) & (r <= 1.25))
            rows.append(
                f"| {k} | {src} | {r.size} ({c['files']}) | {p10:.3f} | {p50:.3f} | {p90:.3f} | "
                f"{100 * inside:.0f} % | {np.exp(np.median(d)):.3f} | "
                f"{np.exp(np.median(dp)):.3f} | "
                f"{c['secs'] / c['files']:.3f} |"
            )
    return "\n".join(rows)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="201,202")
    ap.add_argument("--n", type=int, default=48)
    ap.add_argument(
        "--max-lines",
        type=int,
        default=0,
        help="cap the lines of a system (0: as drawn)",
    )
    ap.add_argument("--out", default="")
    a = ap.parse_args()
    seeds = [int(x) for x in a.seeds.split(",")]
    t0 = time.perf_counter()
    acc, info = run(seeds, a.n, a.max_lines or None)
    wall = time.perf_counter() - t0
    nd = info["nd_calibrated"]
    nd_txt = ", ".join(f"{r}->{c:.1f}" for r, c in nd)
    text = (
        f"Seeds {a.seeds}, {a.n} draws each: {info['files']} systems "
        f"({dict(info['by_kind'])}), {info['skipped']} skipped (generator failure); "
        f"{wall:.0f} s.\n\n"
        + table(acc)
        + f"\n\nh1 files, true records R -> n_d calibrated on the data alone: {nd_txt}\n"
    )
    print(text)
    if a.out:
        Path(a.out).write_text(text)
    print(f"load average {os.getloadavg()[0]:.2f}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
