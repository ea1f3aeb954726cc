"""Real hammer hits: the LADISK impact records (``../shared/realdata``), end to end.

For the five hits together and for each hit alone, `automodal.identify` on the time
records (input stage: hit detection, screening, force window, H1, the band cut at the
hammer's -20 dB point; then the pipeline, split into sub-bands when one model would be
costly). Reported per run: wall time (median of ``--repeat`` runs, the runs of different
inputs interleaved), peak memory of the process, the analysed band, the sub-bands, the
physical modes, which of the README's strong peaks are physical, and the fewest bootstrap
members of a physical mode.

    python benchmarks/bench_impact.py --repeat 3 --out benchmarks/results_impact.md
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from automodal import Settings, identify
from automodal.timedata import TimeSeries

REALDATA = Path(__file__).resolve().parents[2] / "shared" / "realdata"
PEAKS_HZ = (810.0, 900.0, 1518.0, 2640.0, 3008.0, 3669.0, 4128.0, 4164.0, 4392.0)
"""The peaks the data's README names (strong: 3669-4392 Hz; weaker: the others)."""


def hits(which: list[int]) -> TimeSeries:
    """The records of the hits ``which`` (1-5), one after the other."""
    folder = REALDATA / "ladisk_impact_timeseries"
    arrays = [np.load(folder / f"measurements_{k}.npy") for k in which]
    return TimeSeries(outputs=np.concatenate([a[2] for a in arrays])[:, None],
                      inputs=np.concatenate([a[1] for a in arrays])[:, None],
                      sample_rate=25600.0, attributes={"quantity": "acceleration"},
                      source=f"ladisk hits {which}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    if not REALDATA.is_dir():
        print("../shared/realdata is absent: nothing to measure", file=sys.stderr)
        return 0
    cases = {"5 hits": [1, 2, 3, 4, 5], **{f"hit {k}": [k] for k in range(1, 6)}}
    times: dict[str, list[float]] = {name: [] for name in cases}
    last = {}
    for _ in range(args.repeat):
        for name, which in cases.items():
            t0 = time.perf_counter()
            last[name] = identify(hits(which), Settings(seed=0))
            times[name].append(time.perf_counter() - t0)
    rows = ["| input | wall (s, median) | band (Hz) | sub-bands | physical modes "
            "| README peaks physical | fewest members |", "|---|---|---|---|---|---|---|"]
    for name, r in last.items():
        found = np.array([m.frequency_hz for m in r.physical_modes])
        peaks = [f for f in PEAKS_HZ if found.size and np.min(np.abs(found - f)) < 2.0]
        missing = [f"{f:g}" for f in PEAKS_HZ if f not in peaks]
        rows.append(
            f"| {name} | {np.median(times[name]):.1f} | {r.band_hz[0]:.0f}-{r.band_hz[1]:.0f} "
            f"| {len(r.orders.get('sub_bands', [])) or 1} | {len(found)} "
            f"| {len(peaks)}/{len(PEAKS_HZ)}" + (f" (not {', '.join(missing)})" if missing else "")
            + f" | {min((m.n_members for m in r.physical_modes), default=0)} |")
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    load = os.getloadavg()
    text = "\n".join(rows) + (f"\n\nPeak memory of the process {peak_mb:.0f} MB; load average at"
                              f" the end {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} "
                              f"(2 cores); {args.repeat} runs each, interleaved.\n")
    print(text)
    if args.out:
        Path(args.out).write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
