"""Wall time and peak memory of ``automodal identify`` on FRFs with very many lines.

A one-input, one-output receptance with three modes (12.3, 37.1 and 71.9 Hz; damping 1 %,
2 % and 1.5 %) and complex noise of 1 % of its RMS, on 2^p equally spaced lines over
0-100 Hz, written as ``.npz``. Each file is identified once through the command line in a
fresh process (``--seed 1``); the table gives the wall time, the peak resident memory of
that process, the lines analysed and the physical modes found.

    python benchmarks/bench_fine_lines.py [--powers 20,22,24] [--folder DIR]

Results: ``benchmarks/results_fine_lines.md``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from automodal.core.synthesis import modal_poles

MODES = ((12.3, 0.01, 1.0), (37.1, 0.02, 0.7), (71.9, 0.015, 0.5))
"""Natural frequency (Hz), damping ratio and residue of each mode."""


def write_case(path: Path, power: int, seed: int = 1) -> None:
    """The test of 2^power lines, as an ``.npz`` FRF archive."""
    n = 1 << power
    f = np.linspace(0.0, 100.0, n + 1)[1:]
    s = 2j * np.pi * f
    H = np.zeros(n, complex)
    f_n, zeta, residue = (np.array(x) for x in zip(*MODES))
    for lam, a in zip(modal_poles(f_n, zeta), residue):
        H += a / (s - lam) + a / (s - np.conj(lam))
    rng = np.random.default_rng(seed)
    level = 0.01 * np.sqrt(np.mean(np.abs(H) ** 2))
    H += level * (rng.standard_normal(n) + 1j * rng.standard_normal(n)) / np.sqrt(2)
    np.savez(path, frequency=f, frf=H[:, None, None])


def run(path: Path, report: Path) -> tuple[float, float]:
    """Wall time (s) and peak resident memory (GB) of one identification."""
    cmd = [sys.executable, "-m", "automodal", "identify", str(path), "-o", str(report),
           "--seed", "1", "--quiet"]
    start = time.perf_counter()
    proc = subprocess.Popen(cmd)
    _, status, usage = os.wait4(proc.pid, 0)  # the child's own peak memory
    wall = time.perf_counter() - start
    proc.returncode = os.waitstatus_to_exitcode(status)  # reaped here, not by Popen
    if proc.returncode:
        raise SystemExit(f"{path.name}: exit {proc.returncode}")
    return wall, usage.ru_maxrss / 1e6  # KiB on Linux


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--powers", default="20,22,24")
    ap.add_argument("--folder", default=None, help="where the test files go (default a "
                    "temporary folder, removed afterwards)")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(a.folder or tmp)
        folder.mkdir(parents=True, exist_ok=True)
        print("| lines | wall (s) | peak memory (GB) | lines analysed | physical modes (Hz) |")
        print("|---:|---:|---:|---:|---|")
        for p in (int(x) for x in a.powers.split(",")):
            path = folder / f"fine{p}.npz"
            if not path.exists():
                write_case(path, p)
            report = folder / f"fine{p}.json"
            wall, gb = run(path, report)
            rep = json.loads(report.read_text())
            found = ", ".join(f"{m['frequency_hz']:.4f}" for m in rep["modes"] if m["physical"])
            print(f"| 2^{p} | {wall:.1f} | {gb:.2f} | {rep['input']['n_lines_analysed']} |"
                  f" {found} |", flush=True)


if __name__ == "__main__":
    main()
