"""What the imports of one ``automodal identify`` run cost, against the floor of the libraries
a run cannot do without (issue 15, item 11).

For each tree (this one, and optionally ``--other DIR``, e.g. an older checkout), one run
``automodal identify sample_data/chain6.h5 -o report.json`` lists the modules it loaded;
then a fresh interpreter imports exactly those modules, in that order, and its CPU time
(user + system, of the child process) is measured. CPU time rather than wall time, because
the machine is shared: the load of others inflates wall times far more. The floor is an
interpreter importing numpy, scipy.linalg, click and h5py (and, second, the standard
modules a run needs too: multiprocessing, json, concurrent.futures, threadpoolctl).
Bytecode is cached under a temporary ``PYTHONPYCACHEPREFIX``, as it is for an installed
package (without it every run compiles automodal's own modules again).

The issue's own measure, ``python -X importtime`` (wall time of each import, summed), is
printed first, for this tree with its bytecode cached.

    python benchmarks/bench_imports.py                  # this tree and the floor, 7 runs
    python benchmarks/bench_imports.py --other ../old --runs 11
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_data" / "chain6.h5"
FLOOR = "import click, numpy, scipy.linalg, h5py"
FLOOR_STDLIB = "import multiprocessing, json, concurrent.futures, threadpoolctl, " + FLOOR[7:]


def _env(tree: Path, cache: Path) -> dict[str, str]:
    env = dict(os.environ, PYTHONPATH=str(tree), PYTHONPYCACHEPREFIX=str(cache / tree.name))
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def modules_of_a_run(tree: Path, cache: Path, out: Path) -> list[str]:
    """The modules one identify run of ``tree`` loads, in the order they were loaded."""
    code = (
        "import json, sys\nfrom automodal.cli import main\n"
        f"try:\n    main(['identify', {str(SAMPLE)!r}, '-o', {str(out)!r}, '--quiet'])\n"
        "except SystemExit as exc:\n    assert not exc.code, exc.code\n"
        "print(json.dumps(list(sys.modules)))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], cwd=tree, env=_env(tree, cache),
                          capture_output=True, text=True, check=True)
    return [m for m in json.loads(done.stdout.splitlines()[-1]) if m != "__main__"]


def cpu_seconds(tree: Path, cache: Path, code: str) -> float:
    """User + system CPU time of ``python -c code``."""
    child = subprocess.Popen([sys.executable, "-c", code], cwd=tree, env=_env(tree, cache))
    _, status, usage = os.wait4(child.pid, 0)
    if status:
        raise RuntimeError(f"python -c failed ({status})")
    return usage.ru_utime + usage.ru_stime


def importtime_seconds(tree: Path, cache: Path, out: Path) -> float:
    """The issue's own measure: ``python -X importtime -m automodal identify ...`` of
    ``tree``, the modules' self times summed (seconds of wall time, bytecode cached)."""
    done = subprocess.run(
        [sys.executable, "-X", "importtime", "-m", "automodal", "identify", str(SAMPLE),
         "-o", str(out), "--quiet"], cwd=tree, env=_env(tree, cache), capture_output=True,
        text=True, check=True)
    total = 0
    for line in done.stderr.splitlines():
        parts = line.split("|")
        if line.startswith("import time:") and len(parts) == 3 and parts[0][12:].strip().isdigit():
            total += int(parts[0][12:])
    return total / 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--other", type=Path, help="another tree to compare (a checkout)")
    parser.add_argument("--runs", type=int, default=7)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        cache = Path(tmp)
        cases: dict[str, tuple[Path, str]] = {}
        for tree in [ROOT] + ([args.other.resolve()] if args.other else []):
            mods = modules_of_a_run(tree, cache, cache / "report.json")
            code = (f"import importlib\nfor m in {mods!r}:\n    try:\n"
                    "        importlib.import_module(m)\n    except Exception:\n        pass\n")
            cpu_seconds(tree, cache, code)  # fills the bytecode cache
            cases[f"{tree}: the {len(mods)} modules of an identify run"] = (tree, code)
        cases[f"floor: {FLOOR}"] = (ROOT, FLOOR)
        cases[f"floor: {FLOOR_STDLIB}"] = (ROOT, FLOOR_STDLIB)
        cases["python -c pass"] = (ROOT, "pass")
        times: dict[str, list[float]] = {k: [] for k in cases}
        for _ in range(args.runs):  # interleaved, so that a burst of load hits every case
            for k, (tree, code) in cases.items():
                times[k].append(cpu_seconds(tree, cache, code))
        importtime = [importtime_seconds(ROOT, cache, cache / "r.json")
                      for _ in range(args.runs)]
    print(f"`python -X importtime -m automodal identify {SAMPLE.name}`, sum of the modules'"
          f" self times (wall, bytecode cached), {args.runs} runs: median"
          f" {statistics.median(importtime):.3f} s, min {min(importtime):.3f} s\n")
    print(f"CPU seconds (user + system), {args.runs} interleaved runs;"
          f" load average at the end {os.getloadavg()[0]:.2f}")
    print("\n| median | min | what is imported |\n|---:|---:|---|")
    for k, v in times.items():
        print(f"| {statistics.median(v):.3f} | {min(v):.3f} | {k} |")


if __name__ == "__main__":
    main()
