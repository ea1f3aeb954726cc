"""Truth of the time routes of the input stage: simulated time tests of known systems.

For each excitation (`hits`, `random`, `ambient`) and each system and seed,
`automodal.core.simulate_time.simulate_time_test` writes (in memory) a time test with its
exact modes, with the automatic sample rate and duration; `automodal.identify` (input stage
`automodal.core.from_time.as_frfdata`, then the pipeline) finds its modes. A mode is
*clear* when it lies in the analysed band and its largest accelerance peak
``|lambda|^2 |R| / sigma`` (residue over decay rate) is at least 1 % of the largest mode's; it is *found* when a physical mode
lies within 1 % of its frequency. The table gives per route and system: found / clear
modes over the seeds, the largest relative frequency and damping errors of the found ones,
the time to simulate a test and to identify it.

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


def clear_modes(modes: sim.Modes, band_top: float, share: float = 0.01) -> np.ndarray:
    """Indices of the modes in the band whose accelerance peak ``|lambda|^2 |R| / sigma``
    is at least ``share`` of the largest."""
    peak = (np.abs(modes.residues).reshape(modes.n_modes, -1).max(axis=1)
            * np.abs(modes.poles) ** 2 / -modes.poles.real)
    return np.flatnonzero((modes.frequency_hz <= band_top) & (peak >= share * peak.max()))


def score(modes: sim.Modes, found, band_top: float) -> tuple[int, int, float, float]:
    """(found, clear, max |df/f|, max |dzeta/zeta|) of one identification."""
    phys = [m for m in found if m.physical]
    f = np.array([m.frequency_hz for m in phys])
    z = np.array([m.damping_ratio for m in phys])
    n_found, df, dz = 0, 0.0, 0.0
    clear = clear_modes(modes, band_top)
    for r in clear:
        f0, z0 = modes.frequency_hz[r], modes.damping_ratio[r]
        if f.size == 0:
            continue
        k = int(np.argmin(np.abs(f - f0)))
        if abs(f[k] / f0 - 1) < 0.01:
            n_found += 1
            df = max(df, abs(f[k] / f0 - 1))
            dz = max(dz, abs(z[k] / z0 - 1))
    return n_found, clear.size, df, dz


def run(excitation: str, seeds: list[int], noise: float, n_bootstrap: int) -> list[str]:
    rows = []
    for name, (system, force) in systems().items():
        inputs = None if excitation == "ambient" else force
        found = clear = 0
        df = dz = t_sim = t_id = 0.0
        dzs = []
        for seed in seeds:
            t0 = time.perf_counter()
            ts, modes, plan = st.simulate_time_test(system, None, inputs, excitation,
                                                    "acceleration", noise, seed)
            t1 = time.perf_counter()
            result = identify(ts, Settings(seed=seed, n_bootstrap=n_bootstrap, jobs=1))
            t2 = time.perf_counter()
            a, b, c, d = score(modes, result.modes, plan.sample_rate / 2.56)
            found, clear, df, dz = found + a, clear + b, max(df, c), max(dz, d)
            dzs.append(d)
            t_sim, t_id = t_sim + t1 - t0, t_id + t2 - t1
            print(f"{excitation} {name} seed {seed}: {a}/{b} df {c:.2e} dz {d:.3f} "
                  f"({plan.duration:.0f} s at {plan.sample_rate:g} Hz)", file=sys.stderr)
        n = len(seeds)
        rows.append(f"| {excitation} | {name} | {found}/{clear} | {100 * df:.3f} | "
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
        "| route | system | found/clear | max df (%) | max dzeta (%) | median dzeta (%) | "
        "record (s, samples) | simulate (s) | identify (s) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for route in args.routes.split(","):
        lines += run(route, seeds, args.noise, args.bootstrap)
    text = "\n".join(lines)
    print(text)
    if args.out:
        args.out.write_text(text + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
