"""A family of weak-mode test files: the evaluation family's systems with a sensor floor
4, 8 or 16 times as high.

The evaluation family (``../shared/eval/family.py``, which this repository does not hold:
the script stops with a message when it is absent) draws additive noise of 0.5-10 % of
each FRF's RMS, so its modes of matched-filter SNR 10-30 (its "marginal" status) are a few
per hundred files. Here each system is drawn as the family draws it, with additive noise
only, and its level multiplied by 4, 8 or 16 (at most 100 % of the RMS): about one mode in
twenty is then marginal and many clear modes have SNR 30-100. The files, truths and status
are the family's own, so ``family.py score DIR`` scores them.

    python benchmarks/weak_family.py DIR --n 40 --seed 3001
    python ../shared/eval/family.py score DIR

The family's generator stops at a dense grid asking for more outputs than it has masses;
so does this script, with the files written until then.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_noise import FAMILY, load_family  # noqa: E402

FACTORS = (4.0, 8.0, 16.0)
"""The multiples of the family's additive noise level, one drawn per file."""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dir", type=Path)
    ap.add_argument("--n", type=int, default=40, help="files to draw")
    ap.add_argument("--seed", type=int, required=True)
    a = ap.parse_args()
    if not FAMILY.exists():
        sys.exit(f"{FAMILY} is absent: this benchmark needs the evaluation family's generator")
    fam = load_family(FAMILY)
    a.dir.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(a.seed)
    for i in range(a.n):
        try:
            s = fam.make_system(i, rng, ["chain", "grid", "dense"], ["additive"])
        except ValueError as e:  # the family's own limit (see the docstring)
            print(f"stopped at file {i}: {e}")
            break
        s.noise = min(1.0, s.noise * float(rng.choice(FACTORS)))
        s.note = f"{s.note.rsplit(' ', 1)[0]} {s.noise:g}"
        t = fam.write(s, a.dir)
        status = {k: sum(m["status"] == k for m in t["modes"]) for k in fam.ORDER}
        print(s.name, s.note, status, flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
