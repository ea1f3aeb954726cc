"""FE calibration with damping equalization (``automodal calibrate``): coverage and radius of
convergence on the issue's 6-DOF chain. Results in ``benchmarks/results_calibrate.md``.

The chain: 6 masses of 1 kg, springs 1e4 N/m nominal, the true springs off by
-20, +15, -10, +20, +5, -15 %, 1 % Rayleigh damping, 1 % proportional noise, all 6 DOFs
measured, force at DOF 6, 1000 lines to 40 Hz.

``python benchmarks/bench_calibrate.py coverage [N_SEEDS]``
    The whole run (identification, calibration from nominal, 100 bootstrap datasets) on
    N_SEEDS noise realizations: each parameter's error, whether its 95 % interval holds the
    truth, and the ratio of the actual error to the bootstrap std.
``python benchmarks/bench_calibrate.py radius [N_STARTS]``
    From starts with every parameter 30 to 70 % off the truth (random signs), how often
    the calibration reaches the minimum it reaches from the truth (all parameters within
    0.1 % of it), with each damping equalization scheme, on one noisy test data model; and
    how far that minimum is from the truth (the scheme's bias on this noise realization).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import automodal.core.simulate as sim  # noqa: E402
from automodal.app.calibrate import CalibrationSettings, calibrate_data  # noqa: E402
from automodal.core import calibration as cal  # noqa: E402
from automodal.core.damping_equalization import fit_test_model  # noqa: E402
from automodal.core.fe_model import ParametrizedModel  # noqa: E402

N_DOF = 6
DELTA = np.array([-0.2, 0.15, -0.1, 0.2, 0.05, -0.15])
OFFSETS = (0.3, 0.4, 0.5, 0.6, 0.7)
"""How far off the truth the radius test starts every parameter (with a random sign)."""


def chain_model(nominal_theta: np.ndarray | None = None) -> ParametrizedModel:
    """One parameter per spring; ``nominal_theta`` scales the nominal springs."""
    scale = np.ones(N_DOF) if nominal_theta is None else nominal_theta
    nominal = sim.chain(N_DOF, stiffness=1e4 * scale)
    parts = np.array([sim.chain(N_DOF, stiffness=np.eye(N_DOF)[i] * 1e4 * scale[i]).K
                      for i in range(N_DOF)])
    return ParametrizedModel(nominal.K, nominal.M, parts, np.zeros_like(parts),
                             tuple(f"k{i + 1}" for i in range(N_DOF)), np.full(N_DOF, 0.2),
                             np.full(N_DOF, 5.0), np.arange(N_DOF), np.array([N_DOF - 1]))


def chain_data(seed: int, noise: float = 0.01):
    truth = sim.damp(sim.chain(N_DOF, stiffness=1e4 * (1 + DELTA)), "rayleigh", 0.01)
    return sim.simulate_test(truth, np.arange(N_DOF), [N_DOF - 1],
                             sim.frequency_lines(40.0, 1000), noise=noise, seed=seed)


def coverage(n_seeds: int) -> None:
    truth = 1 + DELTA
    hits, errs, zs, times = [], [], [], []
    for seed in range(n_seeds):
        data, _ = chain_data(seed)
        t0 = time.perf_counter()
        r = calibrate_data(data, chain_model(), CalibrationSettings(seed=seed, n_bootstrap=100,
                                                                     jobs=1)).result
        times.append(time.perf_counter() - t0)
        value = np.array([p["value"] for p in r["parameters"]])
        std = np.array([p["std"] for p in r["parameters"]])
        ci = np.array([p["ci95"] for p in r["parameters"]])
        hit = (ci[:, 0] <= truth) & (truth <= ci[:, 1])
        hits.append(hit)
        errs.append(value / truth - 1)
        zs.append((value - truth) / std)
        print(f"seed {seed:2d}: max |error| {100 * np.abs(errs[-1]).max():.4f} %, "
              f"covered {hit.sum()}/6, |z| max {np.abs(zs[-1]).max():.2f}, "
              f"{times[-1]:.1f} s", flush=True)
    hits, errs, zs = np.array(hits), np.array(errs), np.array(zs)
    print(f"\ncoverage {hits.mean():.3f} ({hits.sum()}/{hits.size}); per parameter "
          f"{hits.mean(axis=0).round(2)}; seeds with >= 5 of 6: {(hits.sum(1) >= 5).sum()}"
          f"/{n_seeds}")
    print(f"max |error| {100 * np.abs(errs).max():.4f} %; RMS error / bootstrap std "
          f"{np.sqrt(np.mean(zs**2)):.2f} (1 = intervals of the right width)")
    print(f"runtime median {np.median(times):.1f} s, max {np.max(times):.1f} s")


def radius(n_starts: int) -> None:
    data, modes = chain_data(seed=1)
    omega, H = data.omega, data.frf
    variance = (0.01 * np.abs(H)) ** 2
    truth = 1 + DELTA
    model = chain_model()
    rng = np.random.default_rng(7)
    schemes = [("paired", {}), ("two-stage", {"common_damping": 0.05}),
               ("common", {"common_damping": 0.02}),
               ("common", {"common_damping": 0.05}), ("none", {"fallback_damping": 0.01}),
               ("none", {"fallback_damping": 0.03})]
    print("scheme            | " + " | ".join(f"{100 * o:.0f} % off" for o in OFFSETS)
          + " | evaluations (median) | max |bias| (%)")
    starts = {off: truth * (1 + off * rng.choice([-1, 1], size=(n_starts, N_DOF)))
              for off in OFFSETS}
    for scheme, extra in schemes:
        # the test data model of the noisy data, with its exact poles' refined estimate
        test = cal.refit_test_model(omega, H, variance,
                                        fit_test_model(omega, H, modes.poles, 0, variance))
        problem = cal.CalibrationProblem(model, omega, cal.snr_weights(test.frf(omega),
                                                                       variance), 0,
                                         equalization=scheme.replace("two-stage", "paired"),
                                         **extra)
        solve = cal.calibrate_in_two_stages if scheme == "two-stage" else cal.calibrate
        best = solve(problem, test, truth).theta
        row, evals = [], []
        for off in OFFSETS:
            ok = 0
            for start in starts[off]:
                fit = solve(problem, test, start)
                evals.append(fit.evaluations)
                ok += bool(np.all(np.abs(fit.theta / best - 1) < 0.001))
            row.append(f"{ok:3d}/{n_starts}")
        label = scheme + "".join(f" {v:g}" for v in extra.values())
        bias = 100 * np.abs(best / truth - 1).max()
        print(f"{label:<17} | " + " | ".join(f"{c:>8}" for c in row)
              + f" | {int(np.median(evals)):20d} | {bias:.3f}", flush=True)


if __name__ == "__main__":
    what = sys.argv[1] if len(sys.argv) > 1 else "coverage"
    count = int(sys.argv[2]) if len(sys.argv) > 2 else 20
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1):
        {"coverage": coverage, "radius": radius}[what](count)
