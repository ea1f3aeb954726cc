"""Designed frequency lines (`automodal/core/line_design.py`) against equidistant ones.

For each simulated system and each rule, the same number N of lines over the same band; the
exact FRF (`automodal.core.simulate.frf`) at those lines plus complex Gaussian noise of one
absolute level per FRF entry (``noise`` times the entry's RMS over a dense equidistant grid of
the band, so that every design sees the same sensor noise whatever lines it picks). Measured:

* **core**: the subspace identification (`automodal.core.subspace.identify`) at twice the
  true order; pole errors of every true mode (nearest identified pole), the condition number of
  the monomial Gram matrix of the block rows at the mapped points (what `row_basis` judges),
  and the singular-value gap ``s_n / s_(n+1)`` of the projected data at the true order ``n``;
* **pipeline**: `automodal.identify` (bootstrap, clustering, physicalness; 30 replicates):
  true modes found among the physical modes (within 1 % in frequency) and their errors.

Frequency error: ``|f - f0| / f0``; damping error: ``|zeta - zeta0| / zeta0``; medians over
modes and seeds, and the share of modes the pipeline found. The expected modes given to the
designs are the true ones perturbed (``--expect-error``: frequency by a relative error
N(0, e_f), damping by a factor exp(N(0, e_z))), as a previous test or an FE model would give
them.

The one constant of the rule, `MODAL_SHARE`, is chosen on the calibration seeds
(``--seeds 1-10 --shares ...``); the stored results are measured on seeds 101-120, which it
did not see.

    python benchmarks/bench_design.py --seeds 1-10 --shares 0.25,0.5,0.75,0.9 --no-pipeline
    python benchmarks/bench_design.py --seeds 101-120 --out benchmarks/results_design.md
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from automodal.core import simulate as sim  # noqa: E402
from automodal.core import subspace  # noqa: E402
from automodal.core.bilinear import poles_d2c, to_unit_circle  # noqa: E402
from automodal.core.line_design import MODAL_SHARE, design_lines  # noqa: E402
from automodal.core.subspace import _monomial_gram_cond  # noqa: E402


@dataclass
class Case:
    """One simulated test: a system, its sensors and force, a band and a line count."""

    name: str
    system: sim.MechanicalSystem
    outputs: list[int]
    inputs: list[int]
    band: tuple[float, float]
    n_lines: int


QUANTITY = "acceleration"
"""Accelerances: the modes' peaks are within a decade of each other (in receptance the top
modes of these systems were below 2 % of the RMS, i.e. lost in the noise whatever the lines)."""

CORE_ORDER = 2
"""The core identification's order, in multiples of the true one (over-sized, as the pipeline's
reference model is)."""


def cases() -> list[Case]:
    """The systems: Paper B's 6-DOF chain, a 10-DOF chain with lighter damping and two
    sensors, and a 3 x 4 grid (close modes)."""
    c6 = sim.damp(sim.chain(6), "rayleigh", 0.01)
    f6 = sim.natural_frequencies_hz(c6)
    c10 = sim.damp(sim.chain(10), "nonproportional", 0.005)
    f10 = sim.natural_frequencies_hz(c10)
    g = sim.damp(sim.grid(3, 4), "rayleigh", 0.01)
    fg = sim.natural_frequencies_hz(g)
    return [
        Case("chain6, 6 out, 1 in", c6, list(range(6)), [5],
             (0.5 * f6[0], 1.2 * f6[-1]), 200),
        Case("chain10, 2 out, 1 in, 0.5 %", c10, [3, 9], [9],
             (0.5 * f10[0], 1.1 * f10[-1]), 400),
        Case("grid3x4, 4 out, 2 in", g, [0, 4, 7, 11], [0, 11],
             (0.8 * fg[0], 1.1 * fg[-1]), 300),
    ]


def noisy_frf(case: Case, lines: np.ndarray, level: float, rng: np.random.Generator
              ) -> np.ndarray:
    """FRF at ``lines`` plus noise of the entry's RMS (dense equidistant grid) times ``level``."""
    dense = np.linspace(case.band[0], case.band[1], 4000)
    rms = sim.rms_over_lines(sim.frf(case.system, dense, case.outputs, case.inputs, QUANTITY))
    H = sim.frf(case.system, lines, case.outputs, case.inputs, QUANTITY)
    return H + sim.complex_gaussian(H.shape, level * rms, rng)


def pole_errors(true: np.ndarray, found: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Relative frequency and damping errors of each true pole's nearest found pole."""
    f0, z0 = np.abs(true) / (2 * np.pi), -true.real / np.abs(true)
    if found.size == 0:
        return np.full(true.size, np.nan), np.full(true.size, np.nan)
    idx = np.argmin(np.abs(found[None, :] - true[:, None]), axis=1)
    p = found[idx]
    return np.abs(np.abs(p) / (2 * np.pi) - f0) / f0, np.abs(-p.real / np.abs(p) - z0) / z0


def expected(modes: sim.Modes, rng: np.random.Generator, err_f: float, err_z: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """The true modes, perturbed as prior knowledge would be."""
    f = modes.frequency_hz * (1 + err_f * rng.standard_normal(modes.n_modes))
    z = modes.damping_ratio * np.exp(err_z * rng.standard_normal(modes.n_modes))
    return f, z


def core_run(case: Case, lines: np.ndarray, H: np.ndarray, modes: sim.Modes) -> dict:
    """Subspace identification at the true order: errors and conditioning."""
    from automodal.core.bilinear import default_scale

    n = 2 * modes.n_modes
    omega = 2 * np.pi * lines
    T = default_scale(omega[0], omega[-1])
    z = to_unit_circle(omega, T)
    model = subspace.identify(z, H, CORE_ORDER * n, T, estimate_bd_=False)
    mu = np.linalg.eigvals(model.Ad)
    s = poles_d2c(mu, T)
    s = s[s.imag > 0]
    ef, ez = pole_errors(modes.poles, s)
    basis = subspace.row_basis(z, model.q)
    Hs = H / subspace.channel_scales(H)[None, :, None]
    ev = np.sort(np.linalg.eigvalsh(subspace.single_schur(basis, Hs, None)))[::-1]
    sv = np.sqrt(np.maximum(ev, 0.0))
    return {"ef": ef, "ez": ez, "cond": _monomial_gram_cond(z, model.q),
            "gap": float(sv[n - 1] / sv[n])}


def pipeline_run(case: Case, lines: np.ndarray, H: np.ndarray, modes: sim.Modes,
                 seed: int) -> dict:
    """The whole pipeline: which true modes it finds among its physical modes."""
    import automodal

    data = automodal.FRFData(frequency=lines, frf=H, quantity=QUANTITY)
    res = automodal.identify(data, automodal.Settings(seed=seed, n_bootstrap=30, jobs=1))
    phys = res.physical_modes
    f = np.array([m.frequency_hz for m in phys])
    z = np.array([m.damping_ratio for m in phys])
    ef = np.full(modes.n_modes, np.nan)
    ez = np.full(modes.n_modes, np.nan)
    for i, (f0, z0) in enumerate(zip(modes.frequency_hz, modes.damping_ratio, strict=True)):
        if f.size:
            j = int(np.argmin(np.abs(f - f0)))
            if abs(f[j] - f0) < 0.01 * f0:
                ef[i], ez[i] = abs(f[j] - f0) / f0, abs(z[j] - z0) / z0
    return {"ef": ef, "ez": ez, "extra": max(0, len(phys) - int(np.sum(np.isfinite(ef))))}


def noise_check(all_cases: list[Case], seeds: list[int], level: float) -> list[str]:
    """The data-alone noise model (`core.noise.estimate_noise`, a local polynomial in the line
    index) on equidistant and modal lines: estimated over true noise std per line and entry."""
    from automodal.core.noise import estimate_noise

    out = ["| system | rule | est/true std, median | 90th percentile |", "|---|---|---|---|"]
    for case in all_cases:
        modes = sim.exact_modes(case.system, case.outputs, case.inputs)
        dense = np.linspace(case.band[0], case.band[1], 4000)
        rms = sim.rms_over_lines(sim.frf(case.system, dense, case.outputs, case.inputs,
                                         QUANTITY))
        for rule in ("equidistant", "modal"):
            d = design_lines(case.band, case.n_lines, modes.frequency_hz, modes.damping_ratio,
                             rule=rule)
            r = []
            for seed in seeds:
                H = noisy_frf(case, d.frequency_hz, level, np.random.default_rng(seed))
                ratio = np.sqrt(estimate_noise(H).variance) / (level * rms)
                r.append([np.median(ratio), np.percentile(ratio, 90)])
            med, p90 = np.mean(r, axis=0)
            out.append(f"| {case.name} | {rule} | {med:.2f} | {p90:.2f} |")
    return out


def seeds_of(text: str) -> list[int]:
    """``1-10`` or ``1,2,5``."""
    out: list[int] = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out.extend(range(int(a), int(b) + 1) if b else [int(a)])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="101-120")
    ap.add_argument("--noise", type=float, default=0.02)
    ap.add_argument("--expect-error", type=float, nargs=2, default=(0.01, 0.3),
                    metavar=("E_F", "E_Z"))
    ap.add_argument("--shares", default=None,
                    help="calibration: modal shares to compare (comma list)")
    ap.add_argument("--rules", default="equidistant,dt-uniform,modal,d-optimal")
    ap.add_argument("--no-pipeline", action="store_true")
    ap.add_argument("--cases", default=None, help="indices of the cases to run (comma list)")
    ap.add_argument("--lines", type=int, default=None,
                    help="number of lines for every case (default: each case's own)")
    ap.add_argument("--noise-check", action="store_true",
                    help="only compare the data-alone noise model on equidistant and modal lines")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    seeds = seeds_of(args.seeds)
    variants: list[tuple[str, str, float, float]] = [(r, r, MODAL_SHARE, 0.0)
                                                     for r in args.rules.split(",")]
    if "modal" in args.rules.split(",") and args.expect_error[0] > 0:
        e = args.expect_error[0]
        variants.append((f"modal, uncertainty {100 * e:g} %", "modal", MODAL_SHARE, e))
    if args.shares:
        variants = [("equidistant", "equidistant", 0.0, 0.0)] + [
            (f"modal {float(x):.2f}", "modal", float(x), 0.0) for x in args.shares.split(",")]
    all_cases = cases()
    if args.cases:
        all_cases = [all_cases[int(i)] for i in args.cases.split(",")]
    if args.lines:
        for case in all_cases:
            case.n_lines = args.lines
    if args.noise_check:
        print("\n".join(noise_check(all_cases, seeds, args.noise)))
        return
    t0 = time.time()
    lines_out = [f"load average at start: {os.getloadavg()[0]:.2f}", ""]
    for case in all_cases:
        modes = sim.exact_modes(case.system, case.outputs, case.inputs)
        keep = (modes.frequency_hz >= case.band[0]) & (modes.frequency_hz <= case.band[1])
        assert np.all(keep)
        rows = {name: {"core": [], "pipe": [], "hp": []} for name, *_ in variants}
        for seed in seeds:
            rng = np.random.default_rng(seed)
            fexp, zexp = expected(modes, rng, *args.expect_error)
            noise_seed = int(rng.integers(2**31))
            for name, rule, share, spread in variants:
                d = design_lines(case.band, case.n_lines, fexp, zexp, rule=rule,
                                 modal_share=share, frequency_uncertainty=spread)
                lines = d.frequency_hz
                H = noisy_frf(case, lines, args.noise, np.random.default_rng(noise_seed))
                rows[name]["core"].append(core_run(case, lines, H, modes))
                from automodal.core.line_design import half_power_counts

                rows[name]["hp"].append(half_power_counts(lines, modes.frequency_hz,
                                                          modes.damping_ratio))
                if not args.no_pipeline:
                    rows[name]["pipe"].append(pipeline_run(case, lines, H, modes, seed))
            print(f"{case.name} seed {seed} done ({time.time() - t0:.0f} s)", file=sys.stderr)
        lines_out += table(case, modes, rows, seeds, args)
    lines_out.append(f"total {time.time() - t0:.0f} s")
    text = "\n".join(lines_out)
    print(text)
    if args.out:
        Path(args.out).write_text(text + "\n")


def _pct(a: np.ndarray, q: float) -> str:
    a = a[np.isfinite(a)]
    return f"{100 * np.percentile(a, q):.3f}" if a.size else "n/a"


def table(case: Case, modes: sim.Modes, rows: dict, seeds: list[int], args) -> list[str]:
    """Markdown table of one case."""
    out = [f"### {case.name}: {case.n_lines} lines over {case.band[0]:.3g}-{case.band[1]:.3g}"
           f" Hz, {modes.n_modes} modes ({modes.frequency_hz.min():.3g}-"
           f"{modes.frequency_hz.max():.3g} Hz, damping {100 * modes.damping_ratio.min():.2f}-"
           f"{100 * modes.damping_ratio.max():.2f} %), noise {100 * args.noise:g} %,"
           f" seeds {seeds[0]}-{seeds[-1]} ({len(seeds)})", "",
           "| rule | half-power lines (min/median) | core df/f median (%) | core df/f p90 |"
           " core dzeta/zeta median (%) | p90 | log10 Gram cond (median) |"
           " log10 s_n/s_n+1 (median) | pipeline found | pipe df/f median (%) |"
           " pipe dzeta/zeta median (%) | p90 | extra physical |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, r in rows.items():
        hp = np.concatenate(r["hp"])
        ef = np.concatenate([c["ef"] for c in r["core"]])
        ez = np.concatenate([c["ez"] for c in r["core"]])
        cond = np.median([np.log10(c["cond"]) for c in r["core"]])
        gap = np.median([np.log10(c["gap"]) for c in r["core"]])
        if r["pipe"]:
            pf = np.concatenate([c["ef"] for c in r["pipe"]])
            pz = np.concatenate([c["ez"] for c in r["pipe"]])
            found = f"{np.isfinite(pf).mean():.3f}"
            extra = f"{np.mean([c['extra'] for c in r['pipe']]):.2f}"
            pipe = [found, _pct(pf, 50), _pct(pz, 50), _pct(pz, 90), extra]
        else:
            pipe = ["-"] * 5
        out.append("| " + " | ".join([name, f"{hp.min()}/{np.median(hp):.0f}", _pct(ef, 50),
                                      _pct(ef, 90), _pct(ez, 50), _pct(ez, 90), f"{cond:.1f}",
                                      f"{gap:.2f}", *pipe]) + " |")
    out.append("")
    return out


if __name__ == "__main__":
    main()
