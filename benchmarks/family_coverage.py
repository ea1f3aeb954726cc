"""Coverage of the reported 95 % intervals on scored family files, matched one to one.

``shared/eval/family.py score`` pairs the reported modes of a group of close true modes
(gaps under ``2 zeta f``: on dense grids, chains of many modes) with the group's true modes in
frequency order, so a single missed mode in a group shifts the pairing of every mode above
it, and the intervals of correct estimates are counted against the wrong true modes. This
script pairs every clear true mode (SNR >= 30, away from the band edges) with at most one
physical reported mode, one to one, by the smallest relative frequency distance (the
Hungarian assignment, within the scorer's 2 %), and counts how often the true frequency
and damping lie inside the reported 95 % intervals; it also gives the spread of the
standardised errors ``(estimate - truth) / std`` (median absolute deviation times 1.4826:
1 for calibrated standard deviations), overall and by kind of system and of noise.

    python benchmarks/family_coverage.py DIR [DIR ...]   # folders of f_XX.truth.json and
                                                           # f_XX.report.json (after scoring)
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

F_TOL = 0.02
"""The scorer's frequency tolerance."""


def matched_pairs(truth: dict, report: dict) -> list[dict]:
    """One row per clear true mode matched one to one to a physical reported mode."""
    band = truth["band_hz"]
    true_modes = [m for m in truth["modes"] if m["status"] == "clear"]
    phys = [m for m in report.get("modes", [])
            if m.get("physical") and band[0] <= m["frequency_hz"] <= band[1]]
    if not true_modes or not phys:
        return []
    ft = np.array([m["frequency_hz"] for m in true_modes])
    fr = np.array([m["frequency_hz"] for m in phys])
    cost = np.abs(fr[None, :] / ft[:, None] - 1.0)
    rows, cols = linear_sum_assignment(np.where(cost < F_TOL, cost, 1e6))
    out = []
    for i, j in zip(rows, cols):
        if cost[i, j] >= F_TOL:
            continue
        t, r = true_modes[i], phys[j]
        lo, hi = r["frequency_ci95_hz"]
        zlo, zhi = r["damping_ci95"]
        out.append({
            "cover_f": lo <= t["frequency_hz"] <= hi,
            "cover_z": zlo <= t["damping_ratio"] <= zhi,
            "z_f": (r["frequency_hz"] - t["frequency_hz"]) / max(r["frequency_std_hz"], 1e-300),
            "z_zeta": (r["damping_ratio"] - t["damping_ratio"]) / max(r["damping_std"], 1e-300),
        })
    return out


def _robust_sd(x: np.ndarray) -> float:
    return float(1.4826 * np.median(np.abs(x - np.median(x)))) if x.size else float("nan")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("dirs", nargs="+", type=Path)
    args = parser.parse_args()
    groups: dict[str, list[dict]] = defaultdict(list)
    for folder in args.dirs:
        for tf in sorted(folder.glob("f_*.truth.json")):
            rf = tf.with_name(tf.name.replace(".truth.json", ".report.json"))
            if not rf.exists():
                continue
            truth, report = json.loads(tf.read_text()), json.loads(rf.read_text())
            kind = truth["note"].split(",")[0].strip()
            noise = truth["note"].split(",")[-1].split()[0]
            for row in matched_pairs(truth, report):
                for key in ("all", f"system {kind}", f"noise {noise}"):
                    groups[key].append(row)
    print("| matched clear modes | n | coverage f | coverage zeta | robust sd of (f - f0) / std "
          "| robust sd of (zeta - zeta0) / std |\n|---|---:|---:|---:|---:|---:|")
    for key in sorted(groups, key=lambda k: (k != "all", k)):
        rows = groups[key]
        zf = np.array([r["z_f"] for r in rows])
        zz = np.array([r["z_zeta"] for r in rows])
        print(f"| {key} | {len(rows)} | {np.mean([r['cover_f'] for r in rows]):.3f} | "
              f"{np.mean([r['cover_z'] for r in rows]):.3f} | {_robust_sd(zf):.2f} | "
              f"{_robust_sd(zz):.2f} |")


if __name__ == "__main__":
    main()
