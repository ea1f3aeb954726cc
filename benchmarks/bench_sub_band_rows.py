"""Study: the block rows of the reference model in the sub-bands of a dense MIMO test.

Case b of ``bench_e2e.py`` (8 x 10 grid of masses, 80 modes, 40 outputs on half the grid,
3 inputs, 3000 lines, 1 % proportional noise) is split into sub-bands. Each sub-band's
reference model takes ``q = ceil(1.2 n / r) + 1`` block rows (``r`` the outputs' rank above
the noise, :func:`automodal.core.subspace.reference_block_rows`), while the order scan uses
``q ny >= 3 n`` (:func:`automodal.core.subspace.scan_block_rows`). This script measures what
the reference's block rows do to the modes of those sub-bands; it changes nothing in the
package.

Parts:

1. **Rules**: ``pipeline.identify`` with the block rows of every (sub-)band's reference
   raised by a rule (``order.select_orders`` wrapped, so the split decision, which counts
   the block rows in a replicate's work, sees them too), at most what the replicates'
   lines allow:

   - ``default``: the package as it is;
   - ``scan``: ``q ny >= 3 n_ref``, the scan's rule at the reference order;
   - ``scan where r < ny``: the same, only where the outputs show fewer directions than
     sensors;
   - ``rank``: ``q r >= 3 n_ref``.
   - ``block_rows=Q``: the package's ``Settings(block_rows=Q)`` (``--block-rows Q``),
     for each ``Q`` of ``--block-rows``.

   Physical rows, true modes found (one-to-one within 1 %), rows matching no true mode,
   sub-bands, wall time (all cores unless ``--jobs``).
2. **One reference per sub-band** (the default run's noise-weighted sub-bands): the
   reference model alone (``reference.build_reference``) at the default ``q`` and at larger
   ones: true modes of the analysed band whose closest candidate is within 1e-3 in
   frequency and 10 % in damping (the closest pole of each true mode: two close modes may
   share one, so the count is an upper bound), median errors, and the dispersion
   (whitened residual of the reference's modal model over its degrees of freedom), which
   the pipeline uses.

Run ``python benchmarks/bench_sub_band_rows.py --help`` for the options.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from unittest import mock

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
from bench_e2e import (  # noqa: E402
    CASES,
    automodal_cmd,
    blas_line,
    git_state,
    load_average,
    match_modes,
    run_child,
)

from automodal import pipeline  # noqa: E402
from automodal.core import order, reference, subspace, whitening  # noqa: E402
from automodal.io.frf_file import read_frf  # noqa: E402
from automodal.settings import Settings  # noqa: E402

RULES = ("default", "scan", "scan where r < ny", "rank")
Q_FACTORS = (1.0, 1.5, 2.0, 3.0)
FREQ_TOL, DAMP_TOL = 1e-3, 0.1


def simulate(workdir: Path) -> tuple[Path, dict]:
    """Case b; its path and true modes."""
    path = workdir / "b.h5"
    run_child(automodal_cmd() + ["simulate", str(path), *CASES["b"]["simulate"], "-q"])
    return path, json.loads(path.with_suffix(".modes.json").read_text())


def raised_rows(rule: str, choice: order.OrderChoice, H: np.ndarray,
                rank: int | None) -> int:
    """The reference's block rows under ``rule``, at most the replicates' line budget."""
    N, ny, nu = H.shape
    q = choice.block_rows
    rows = order.block_row_budget(N, ny, nu)
    n = choice.reference
    if rule == "scan" or (rule == "scan where r < ny" and rank is not None and rank < ny):
        q = max(q, min(subspace.scan_block_rows(n, ny), rows))
    elif rule == "rank":
        r = ny if rank is None else max(2, min(int(rank), ny))
        q = max(q, min(int(np.ceil(3.0 * n / r)) + 1, rows))
    return q


def run_rule(data, rule: str, true_f: np.ndarray, jobs: int | None,
             block_rows: int | None = None) -> dict:
    """One pipeline run with ``rule`` (and ``Settings.block_rows``); its counts and the
    sub-bands' reference orders."""
    select, identify_part = order.select_orders, pipeline._identify
    parts: list[dict] = []

    def selected(z, H, weights, *args, **kwargs):
        choice = select(z, H, weights, *args, **kwargs)
        return replace(choice, block_rows=raised_rows(rule, choice, H, kwargs.get("rank")))

    def part(d, s, *args, **kwargs):
        res = identify_part(d, s, *args, **kwargs)
        if kwargs.get("part") and res.orders and "sub_bands" not in res.orders:
            # a sub-band that was not split again
            parts.append({"band": res.band_hz, "n_ref": res.orders["reference"],
                          "q": res.orders["block_rows"], "weighting": res.orders["weighting"]})
        return res

    with mock.patch.object(order, "select_orders", selected), \
            mock.patch.object(pipeline, "_identify", part):
        t0 = time.perf_counter()
        res = pipeline.identify(data, Settings(seed=0, jobs=jobs, block_rows=block_rows))
        dt = time.perf_counter() - t0
    phys = [m.frequency_hz for m in res.modes if m.physical]
    found, extra = match_modes(phys, list(true_f))
    if block_rows is not None:
        rule = f"block_rows={block_rows}"
    print(f"  rule {rule}: {found} found, {extra} extra, {dt:.1f} s", file=sys.stderr)
    return {"rule": rule, "physical": len(phys), "found": found, "extra": extra, "time": dt,
            "parts": sorted(parts, key=lambda p: p["band"][0])}


def reference_rows(data, parts: list[dict], truth: dict) -> list[dict]:
    """The reference alone, per noise-weighted sub-band, at several block rows."""
    f_true = np.asarray(truth["frequency_hz"], float)
    z_true = np.asarray(truth["damping_ratio"], float)
    rows = []
    for p in parts:
        if p["weighting"] != "noise":
            continue
        prep = pipeline.prepare(data, Settings(band_hz=tuple(p["band"])), [])
        N, ny, nu = prep.Hs.shape
        budget = order.block_row_budget(N, ny, nu)
        inside = (f_true > p["band"][0]) & (f_true < p["band"][1])
        for factor in Q_FACTORS:
            q = min(int(round(factor * p["q"])), budget)
            t0 = time.perf_counter()
            ref = reference.build_reference(
                prep.z, prep.Hs, prep.scales, prep.line_weights, p["n_ref"], prep.T,
                prep.band_rad_s, 0.2, 1.0, prep.pole_map, q)
            dt = time.perf_counter() - t0
            lam = ref.modes.poles
            f = np.abs(lam) / (2 * np.pi)
            zeta = -lam.real / np.abs(lam)
            df, dz = [], []
            for f0, z0 in zip(f_true[inside], z_true[inside]):
                j = int(np.argmin(np.abs(f - f0)))
                df.append(abs(f[j] - f0) / f0)
                dz.append(abs(zeta[j] - z0) / z0)
            df, dz = np.array(df), np.array(dz)
            disp = whitening.dispersion(ref.modal.frequency_response(prep.z), prep.Hs,
                                        prep.variance, p["n_ref"])
            rows.append({"band": p["band"], "n_ref": p["n_ref"], "q": q, "ny": ny,
                         "true": int(inside.sum()),
                         "good": int(np.sum((df < FREQ_TOL) & (dz < DAMP_TOL))),
                         "df": float(np.median(df)), "dz": float(np.median(dz)),
                         "disp": float(disp), "time": dt})
            print(f"  reference {p['band'][0]:.2f}-{p['band'][1]:.2f} Hz q={q}:"
                  f" {rows[-1]['good']}/{rows[-1]['true']}", file=sys.stderr)
    return rows


def render(meta: dict, runs: list[dict], refs: list[dict]) -> str:
    out = ["# Block rows of the reference in a dense MIMO test's sub-bands (case b)", ""]
    out += [f"* {k}: {v}" for k, v in meta.items()]
    out += ["", "## Rules for the reference's block rows (pipeline, 1 % noise)", "",
            "| rule | physical rows | true modes found (of 80) | physical rows matching no"
            " true mode | sub-bands | wall s |", "|---|---:|---:|---:|---:|---:|"]
    for r in runs:
        out.append(f"| {r['rule']} | {r['physical']} | {r['found']} | {r['extra']} |"
                   f" {len(r['parts'])} | {r['time']:.1f} |")
    out += ["", "Sub-bands of each run (analysed band Hz, reference order, block rows,"
            " weighting):", ""]
    for r in runs:
        text = "; ".join(f"{p['band'][0]:.2f}-{p['band'][1]:.2f}: {p['n_ref']}, q {p['q']},"
                         f" {p['weighting']}" for p in r["parts"])
        out.append(f"* {r['rule']}: {text}")
    out += ["", "## The reference alone in the default run's noise-weighted sub-bands", "",
            f"True modes of the analysed band whose closest candidate pole is within"
            f" {FREQ_TOL:g} (relative frequency) and {100 * DAMP_TOL:g} % (relative damping);"
            " two close modes may share a pole, so the count is an upper bound.",
            "", "| band Hz | outputs | reference order | q | q ny / n | true modes right |"
            " median error f | median error zeta | dispersion | s |",
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in refs:
        out.append(f"| {r['band'][0]:.2f}-{r['band'][1]:.2f} | {r['ny']} | {r['n_ref']} |"
                   f" {r['q']} | {r['q'] * r['ny'] / r['n_ref']:.1f} | {r['good']} / {r['true']}"
                   f" | {r['df']:.1e} | {r['dz']:.1e} | {r['disp']:.3g} | {r['time']:.2f} |")
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rules", default=",".join(RULES),
                    help=f"rules to run, comma-separated (default: {', '.join(RULES)})")
    ap.add_argument("--block-rows", default="14,18",
                    help="values of Settings.block_rows to run (default: 14,18; '' for none)")
    ap.add_argument("--jobs", type=int, default=None, help="worker threads (default: all)")
    ap.add_argument("--out", metavar="FILE.md", help="also write the report to this file")
    args = ap.parse_args(argv)
    rules = [r.strip() for r in args.rules.split(",") if r.strip()]
    unknown = sorted(set(rules) - set(RULES))
    if unknown:
        ap.error(f"unknown rules {unknown}; known: {', '.join(RULES)}")
    meta = {"automodal": f"git {git_state()}", "BLAS": blas_line(),
            "load average at start": load_average()}
    with tempfile.TemporaryDirectory() as tmp:
        path, truth = simulate(Path(tmp))
        data = read_frf(str(path))
        true_f = np.asarray(truth["frequency_hz"], float)
        runs = [run_rule(data, rule, true_f, args.jobs) for rule in rules]
        runs += [run_rule(data, "default", true_f, args.jobs, int(q))
                 for q in args.block_rows.split(",") if q.strip()]
        base = next((r for r in runs if r["rule"] == "default"), None)  # the package's
        from threadpoolctl import threadpool_limits

        with threadpool_limits(1):
            refs = reference_rows(data, base["parts"], truth) if base else []
    meta["load average at end"] = load_average()
    text = render(meta, runs, refs)
    if args.out:
        Path(args.out).write_text(text)
    sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
