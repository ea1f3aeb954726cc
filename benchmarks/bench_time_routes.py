"""Truth of the time routes of the input stage: simulated time tests of known systems.

For each excitation (`hits`, `random`, `ambient`) and each system and seed,
`automodal.core.simulate_time.simulate_time_test` writes (in memory) a time test with its
exact modes, with the automatic sample rate and duration; `automodal.identify` (input stage
`automodal.core.from_time.as_frfdata`, then the pipeline) finds its modes. A mode is
*clear* when it lies in the analysed band and its accelerance peak is at least 1 % of the
largest mode's (`automodal.core.simulate_time.clear_modes`); it is *found* when a physical
mode lies within 1 % of its frequency (the nearest one is compared); *extra physical*
counts the physical modes that are no clear mode's nearest (spurious or doubled modes).
The table gives per route and system, over the seeds: found / clear modes, extra physical
modes, the largest relative frequency and damping errors of the found modes (and the
median over seeds of each seed's largest damping error), the record, and the time to
simulate a test and to identify it.

    python benchmarks/bench_time_routes.py --seeds 11,12,13 --out benchmarks/results_time_routes.md
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from automodal import Settings, identify
from automodal.core import simulate as sim
from automodal.core import simulate_time as st


def systems() -> dict[str, tuple[sim.MechanicalSystem, list[int]]]:
    """The systems with their force DOF (last DOF; ambient: all DOFs)."""
    out = {}
    for n in (3, 4, 6):
        out[f"chain{n}"] = (sim.damp(sim.chain(n), zeta=0.01), [n - 1])
    out["grid3x2"] = (sim.damp(sim.grid(3, 2), zeta=0.01), [5])
    out["chain5 np"] = (sim.damp(sim.chain(5), "nonproportional", 0.02), [4])
    return out


def score(modes: sim.Modes, found, band_top: float) -> tuple[int, int, float, float, int]:
    """(found, clear, max |df/f|, max |dzeta/zeta|, spurious) of one identification:
    spurious counts the physical modes that are no clear mode's nearest."""
    phys = [m for m in found if m.physical]
    f = np.array([m.frequency_hz for m in phys])
    z = np.array([m.damping_ratio for m in phys])
    clear = st.clear_modes(modes, band_top, "acceleration")
    k = st.nearest_modes(modes.frequency_hz[clear], f)
    hit = k >= 0
    if not hit.any():
        return 0, clear.size, 0.0, 0.0, len(phys)
    df = np.abs(f[k[hit]] / modes.frequency_hz[clear][hit] - 1)
    dz = np.abs(z[k[hit]] / modes.damping_ratio[clear][hit] - 1)
    return int(hit.sum()), clear.size, float(df.max()), float(dz.max()), len(phys) - hit.sum()


def run(excitation: str, seeds: list[int], noise: float, n_bootstrap: int) -> list[str]:
    rows = []
    for name, (system, force) in systems().items():
        inputs = None if excitation == "ambient" else force
        found = clear = spurious = 0
        df = dz = t_sim = t_id = 0.0
        dzs = []
        for seed in seeds:
            t0 = time.perf_counter()
            ts, modes, plan = st.simulate_time_test(system, None, inputs, excitation,
                                                    "acceleration", noise, seed)
            t1 = time.perf_counter()
            result = identify(ts, Settings(seed=seed, n_bootstrap=n_bootstrap, jobs=1))
            t2 = time.perf_counter()
            a, b, c, d, e = score(modes, result.modes, plan.sample_rate / 2.56)
            found, clear, df, dz = found + a, clear + b, max(df, c), max(dz, d)
            spurious += e
            dzs.append(d)
            t_sim, t_id = t_sim + t1 - t0, t_id + t2 - t1
            print(f"{excitation} {name} seed {seed}: {a}/{b} df {c:.2e} dz {d:.3f} +{e} "
                  f"({plan.duration:.0f} s at {plan.sample_rate:g} Hz)", file=sys.stderr)
        n = len(seeds)
        rows.append(f"| {excitation} | {name} | {found}/{clear} | {spurious} | {100 * df:.3f} | "
                    f"{100 * dz:.1f} | {100 * float(np.median(dzs)):.1f} | "
                    f"{plan.duration:.0f} s, {plan.n_samples} | {t_sim / n:.2f} | "
                    f"{t_id / n:.2f} |")
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="11,12,13")
    parser.add_argument("--routes", default="hits,random,ambient")
    parser.add_argument("--noise", type=float, default=0.01)
    parser.add_argument("--bootstrap", type=int, default=50)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")]
    lines = [
        f"seeds {args.seeds}, noise {args.noise:g} (std / channel RMS), acceleration, "
        f"{args.bootstrap} bootstrap replicates, jobs 1; load average "
        f"{os.getloadavg()[0]:.2f} at the start (shared 2-core machine: times inflated)",
        "",
        "| route | system | found/clear | extra physical | max df (%) | max dzeta (%) | "
        "median dzeta (%) | record (s, samples) | simulate (s) | identify (s) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for route in args.routes.split(","):
        lines += run(route, seeds, args.noise, args.bootstrap)
    text = "\n".join(lines)
    print(text)
    if args.out:
        args.out.write_text(text + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
