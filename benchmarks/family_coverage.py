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

A second table pairs as the scorer does: the true modes fall into groups of close modes
(each gap under ``2 zeta f`` of either neighbour or 0.2 % of ``f``); a physical mode joins
the group of its nearest true mode within 2 % (the scorer also asks for a MAC above 0.8,
left out here); a group expects ``min(size, rank)`` modes (``rank`` the smaller of the
outputs and inputs), credits its most physical ones and pairs them with its lowest true
modes in frequency order. It splits the coverage by groups of one mode, groups the data's
rank can resolve, and groups larger than it, where a mode correct to its interval is still
counted against whichever of the group's lowest true modes it was paired with.

    python benchmarks/family_coverage.py DIR [DIR ...]   # folders of NAME.truth.json and
                                                           # NAME.report.json (after scoring)
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from collections.abc import Iterator
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


def close_groups(true_modes: list[dict]) -> list[list[int]]:
    """Indices of the true modes (sorted by frequency) in groups of close modes, as the
    scorer forms them."""
    groups: list[list[int]] = []
    for i, m in enumerate(true_modes):
        if groups:
            p = true_modes[groups[-1][-1]]
            gap = m["frequency_hz"] - p["frequency_hz"]
            if gap < max(2 * m["damping_ratio"] * m["frequency_hz"],
                         2 * p["damping_ratio"] * p["frequency_hz"], 0.002 * m["frequency_hz"]):
                groups[-1].append(i)
                continue
        groups.append([i])
    return groups


def scorer_pairs(truth: dict, report: dict) -> list[dict]:
    """Coverage rows of the scorer's pairing (frequency only, see the module's text), each
    with its group's class: ``"one mode"``, ``"within rank"`` or ``"beyond rank"``."""
    band = truth["band_hz"]
    tm = sorted(truth["modes"], key=lambda m: m["frequency_hz"])
    rank = truth.get("rank", 99)
    phys = [m for m in report.get("modes", [])
            if m.get("physical") and band[0] <= m["frequency_hz"] <= band[1]]
    groups = close_groups(tm)
    owner = {j: gi for gi, g in enumerate(groups) for j in g}
    ft = np.array([m["frequency_hz"] for m in tm])
    found: dict[int, list[dict]] = defaultdict(list)
    for r in phys:
        d = np.abs(r["frequency_hz"] / ft - 1.0) if ft.size else np.zeros(0)
        if d.size and d.min() < F_TOL:
            found[owner[int(np.argmin(d))]].append(r)
    out = []
    for gi, g in enumerate(groups):
        expect = min(len(g), rank)
        got = sorted(found.get(gi, []), key=lambda r: -r.get("physicalness", 1))[:expect]
        kind = "one mode" if len(g) == 1 else ("within rank" if len(g) <= rank
                                               else "beyond rank")
        for r, j in zip(sorted(got, key=lambda r: r["frequency_hz"]), g):
            t = tm[j]
            lo, hi = r["frequency_ci95_hz"]
            zlo, zhi = r["damping_ci95"]
            out.append({"group": kind, "cover_f": lo <= t["frequency_hz"] <= hi,
                        "cover_z": zlo <= t["damping_ratio"] <= zhi})
    return out


def _robust_sd(x: np.ndarray) -> float:
    return float(1.4826 * np.median(np.abs(x - np.median(x)))) if x.size else float("nan")


def scored_cases(dirs: list[Path]) -> Iterator[tuple[Path, dict, dict]]:
    """``(truth file, truth, report)`` of every scored case in ``dirs``: each
    ``NAME.truth.json`` beside a ``NAME.report.json``, in name order."""
    for folder in dirs:
        for tf in sorted(folder.glob("*.truth.json")):
            rf = tf.with_name(tf.name.replace(".truth.json", ".report.json"))
            if rf.exists():
                yield tf, json.loads(tf.read_text()), json.loads(rf.read_text())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("dirs", nargs="+", type=Path)
    args = parser.parse_args()
    groups: dict[str, list[dict]] = defaultdict(list)
    paired: dict[str, list[dict]] = defaultdict(list)
    for _, truth, report in scored_cases(args.dirs):
        kind = truth["note"].split(",")[0].strip()
        noise = truth["note"].split(",")[-1].split()[0]
        for row in matched_pairs(truth, report):
            for key in ("all", f"system {kind}", f"noise {noise}"):
                groups[key].append(row)
        for row in scorer_pairs(truth, report):
            for key in ("all", f"{row['group']}", f"{row['group']}, {kind}"):
                paired[key].append(row)
    print("| matched clear modes | n | coverage f | coverage zeta | robust sd of (f - f0) / std "
          "| robust sd of (zeta - zeta0) / std |\n|---|---:|---:|---:|---:|---:|")
    for key in sorted(groups, key=lambda k: (k != "all", k)):
        rows = groups[key]
        zf = np.array([r["z_f"] for r in rows])
        zz = np.array([r["z_zeta"] for r in rows])
        print(f"| {key} | {len(rows)} | {np.mean([r['cover_f'] for r in rows]):.3f} | "
              f"{np.mean([r['cover_z'] for r in rows]):.3f} | {_robust_sd(zf):.2f} | "
              f"{_robust_sd(zz):.2f} |")
    print("\n| the scorer's pairing, every hit | n | coverage f | coverage zeta |"
          "\n|---|---:|---:|---:|")
    for key in sorted(paired, key=lambda k: (k != "all", k)):
        rows = paired[key]
        print(f"| {key} | {len(rows)} | {np.mean([r['cover_f'] for r in rows]):.3f} | "
              f"{np.mean([r['cover_z'] for r in rows]):.3f} |")


if __name__ == "__main__":
    main()
