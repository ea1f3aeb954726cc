"""What the inputs let the data show of each group of close true modes the scorer counts missed.

``shared/eval/family.py score`` expects ``min(size, rank)`` modes of a group of close true
modes (``rank`` the smaller of the outputs and inputs) and calls the group's modes clear by
each mode's own matched-filter SNR. Two modes on one pole (a nearly square grid's repeated
pair, ``0.001-0.02`` half-bandwidths apart) are two modes in the data only as far as their
residues are not one matrix of rank one: if the inputs see both modes' shapes in nearly one
proportion, the pair's FRF is one mode's plus a second direction far weaker than either
mode. This script prints, for every missed group, its modes' frequencies and SNRs, the gaps
in half-bandwidths, and the singular values of ``sum_r SNR_r u_r v_r^H`` (``u_r``, ``v_r``
the mode's output and input shapes at unit norm), least and most over the modes' relative
signs, which the truth files do not keep (their shapes are scaled to their largest entry;
the family's modes are real): each direction's approximate SNR. Where
the direction the scorer's count needs last (the ``min(size, rank)``-th) is below about 10,
no detector finds that mode; 10-30 is the scorer's marginal range. (An estimate, which
ignores how the noise varies over the lines and entries: against the second singular value
of the simulated systems' own summed residues times the group's SNR, 13.0-14.2 for 12.4
(seed 2399 f_01), 12.8 for 12.8 (2411 f_04), 6.8 for 6.8 (2447 f_22), but 53-54 for 23 where
one mode is 7.6 times the other under proportional noise (2447 f_10).)

    python benchmarks/family_missed_groups.py DIR [DIR ...] [--family ../shared/eval/family.py]
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_noise import FAMILY, load_family  # noqa: E402
from family_coverage import scored_cases  # noqa: E402


def describe(group: list[dict], vector: Callable[[dict], np.ndarray]) -> dict:
    """The group's frequencies, SNRs, gaps (half-bandwidths of the lower mode) and each
    direction's approximate SNR, least and most over the modes' unknown relative signs
    (``vector``: a truth file's ``{"real", "imag"}`` shape as a complex array, the
    scorer's own)."""
    f = np.array([m["frequency_hz"] for m in group])
    zeta = np.array([m["damping_ratio"] for m in group])
    snr = np.array([m["snr"] for m in group])
    terms = []
    for m, weight in zip(group, snr):
        u, v = vector(m["mode_shape"]), vector(m["input_shape"])
        terms.append(weight * np.outer(u / np.linalg.norm(u), (v / np.linalg.norm(v)).conj()))
    sv = np.array([np.linalg.svd(sum(sign * t for sign, t in zip((1,) + signs, terms)),
                                 compute_uv=False)
                   for signs in itertools.product((1, -1), repeat=len(terms) - 1)])
    return {"frequency_hz": f.round(4).tolist(), "snr": snr.round().astype(int).tolist(),
            "gap_half_bandwidths": (np.diff(f) / (zeta[:-1] * f[:-1])).round(3).tolist(),
            "direction_snr": [[round(float(lo), 1), round(float(hi), 1)]
                              for lo, hi in zip(sv.min(axis=0), sv.max(axis=0))]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dirs", nargs="+", type=Path)
    ap.add_argument("--family", type=Path, default=FAMILY)
    a = ap.parse_args()
    fam = load_family(a.family)
    for tp, truth, report in scored_cases(a.dirs):
        missed = fam.score_case(truth, report)["missed_clear"]
        if not missed:
            continue
        modes = truth["modes"]
        for group in fam._groups(modes):
            first = round(modes[group[0]]["frequency_hz"], 3)
            if any(first == m[0] for m in missed):
                name = tp.name.removesuffix(".truth.json")
                print(f"{tp.parent.name}/{name}", truth["note"], f"rank {truth['rank']}",
                      json.dumps(describe([modes[j] for j in group], fam._shape)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
