"""Simulated tests with known modes, shared by the pipeline tests and the benchmarks."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from automodal.core import simulate as sim
from automodal.frfdata import FRFData


@dataclass
class Case:
    """A simulated test and the true modes inside its band."""

    name: str
    data: FRFData
    true_hz: np.ndarray
    true_zeta: np.ndarray


def _case(name, system, outputs, inputs, quantity, noise, seed, n_lines=1000, fmax_factor=1.25,
          pure_noise=False) -> Case:
    fmax = fmax_factor * sim.natural_frequencies_hz(system).max()
    freq = sim.frequency_lines(fmax, n_lines)
    data, modes = sim.simulate_test(system, outputs, inputs, freq, quantity, noise=noise,
                                    seed=seed, pure_noise=pure_noise)
    inband = (modes.frequency_hz >= freq[0]) & (modes.frequency_hz <= freq[-1])
    return Case(name, data, modes.frequency_hz[inband], modes.damping_ratio[inband])


def chain6_1pct(seed: int = 1) -> Case:
    """6-DOF chain, 6 outputs, 1 input, 1 % noise."""
    return _case("chain6_1pct", sim.damp(sim.chain(6), zeta=0.01), range(6), [5],
                 "displacement", 0.01, seed)


def chain10_5pct(seed: int = 2) -> Case:
    """10-DOF chain, 5 outputs, 1 input, 5 % noise."""
    return _case("chain10_5pct", sim.damp(sim.chain(10), zeta=0.01), [1, 3, 5, 7, 9], [9],
                 "displacement", 0.05, seed)


def near_repeated(seed: int = 3) -> Case:
    """Symmetric 3x3 grid (repeated pairs) seen by two inputs at adjacent corners."""
    system = sim.damp(sim.grid(3, 3, symmetric=True), zeta=0.01)
    return _case("near_repeated", system, range(9), [0, 5], "displacement", 0.005, seed)


def spatial_aliasing(seed: int = 4) -> Case:
    """12-DOF chain, 4 sensors, 12 modes in band."""
    return _case("spatial_aliasing", sim.damp(sim.chain(12), zeta=0.01), [2, 5, 8, 11], [11],
                 "displacement", 0.01, seed, n_lines=2000)


def nonprop_accelerance(seed: int = 5) -> Case:
    """3x4 grid, non-proportional damping, accelerance, 2 inputs, 1 % noise."""
    system = sim.damp(sim.grid(3, 4), "nonproportional", zeta=0.01)
    return _case("nonprop_accelerance", system, [0, 1, 2, 4, 6, 7, 9, 11], [0, 11],
                 "acceleration", 0.01, seed)


def pure_noise(seed: int = 6) -> Case:
    """Complex Gaussian noise at a chain's level: no structure at all."""
    return _case("pure_noise", sim.damp(sim.chain(6), zeta=0.01), range(6), [5],
                 "displacement", 0.01, seed, pure_noise=True)


ALL = [chain6_1pct, chain10_5pct, near_repeated, spatial_aliasing, nonprop_accelerance, pure_noise]


def score(case: Case, modes, tol: float = 0.01) -> dict:
    """Recall, precision and frequency errors of the physical modes against the truth.

    A physical mode matches the nearest unmatched true mode within ``tol`` (relative).
    """
    phys = sorted((m for m in modes if m.physical), key=lambda m: m.frequency_hz)
    free = list(range(case.true_hz.size))
    matched, errors = 0, []
    for m in phys:
        if not free:
            break
        rel = np.abs(case.true_hz[free] - m.frequency_hz) / case.true_hz[free]
        j = int(np.argmin(rel))
        if rel[j] < tol:
            errors.append(float(rel[j]))
            free.pop(j)
            matched += 1
    n_true = case.true_hz.size
    return {
        "n_true": n_true,
        "n_physical": len(phys),
        "recall": matched / n_true if n_true else 1.0,
        "precision": matched / len(phys) if phys else 1.0,
        "median_rel_error": float(np.median(errors)) if errors else 0.0,
        "max_rel_error": float(np.max(errors)) if errors else 0.0,
    }
