"""Study: how many block rows ``q`` a test with many outputs and many modes needs.

Case b of ``bench_e2e.py`` (8 x 10 grid of masses, 80 modes, 40 outputs on half the grid,
3 inputs, 3000 lines) loses half its modes and reports spurious "physical" ones with the
default ``q = block_rows(n, ny)`` (``q ny`` about ``1.2 n``). This script measures why and
what a larger ``q`` would cost; it changes nothing in the package.

Parts:

1. **One identification** (``subspace.identify`` with the package's automatic route and
   row basis, the pipeline's preparation and line weights) at orders 160 (the true order)
   and 228 (the pipeline's reference order) for several ``q``, on the noise-free and the
   1 % noise file: true modes found within 1e-6, 1e-3 and 1e-2 (relative frequency),
   median error, and the n-th singular value of the projected data.
2. **Replicate Gram sums at a large q**: the orthonormal row basis (the one ``row_basis``
   chooses there) makes every Gram block a sum over ``q^2`` basis products instead of the
   ``2 q - 1`` power sums of the monomial basis. Alternative measured here: the monomial
   power sums turned into the orthonormal basis by the congruence with the basis'
   monomial coefficients (``P = C W``, so ``G_orth = C G_mono C^T`` block by block); its
   rounding error grows like ``eps cond(monomial Gram)``.
3. ``--pipeline`` (slow, about 7 minutes): ``pipeline.identify`` with the block rows of
   the reference model and replicates raised to at least ``Q`` (``block_rows`` patched
   for the run): modes found, spurious physical rows, wall time; the largest ``Q`` once
   more with the replicates' sums by the congruence (``gram_sums`` patched too).

Run ``python benchmarks/bench_block_rows.py --help`` for the options.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from unittest import mock

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
from bench_e2e import (  # noqa: E402
    CASES,
    automodal_cmd,  # noqa: E402
    blas_line,
    git_state,
    load_average,
    match_modes,
    run_child,
)

from automodal import pipeline  # noqa: E402
from automodal.core import subspace  # noqa: E402
from automodal.core.clustering import physical_candidates  # noqa: E402
from automodal.core.modal import modes_of_discrete  # noqa: E402
from automodal.io.frf_file import read_frf  # noqa: E402
from automodal.settings import Settings  # noqa: E402

ORDERS = (160, 228)
BLOCK_ROWS = (8, 12, 16, 20, 28)
GRAM_Q = 19  # q ny >= 3 n at the reference order 228 (the scan's rule, scan_block_rows)
PIPELINE_Q = (8, 13, 19)
DEFAULT_GRAM_SUMS = subspace.gram_sums


def simulate(workdir: Path, noise: float) -> tuple[Path, np.ndarray]:
    """Case b with the given noise level; its path and true natural frequencies."""
    args = list(CASES["b"]["simulate"])
    args[args.index("--noise") + 1] = str(noise)
    path = workdir / f"b_noise{noise:g}.h5"
    run_child(automodal_cmd() + ["simulate", str(path), *args, "-q"])
    modes = json.loads(path.with_suffix(".modes.json").read_text())
    return path, np.asarray(modes["frequency_hz"], float)


def in_band_poles(A: np.ndarray, C: np.ndarray, prep: pipeline.Prepared) -> np.ndarray:
    """Natural frequencies (Hz) of the modes of (A, C) that the pipeline would take as
    physical candidates (``clustering.physical_candidates``)."""
    m = modes_of_discrete(A, C, prep.T)
    band = (2 * np.pi * prep.band_hz[0], 2 * np.pi * prep.band_hz[1])
    return np.abs(m.poles[physical_candidates(m.poles, band)]) / (2 * np.pi)


def errors(found: np.ndarray, true: np.ndarray) -> np.ndarray:
    """Relative error of the closest found frequency, per true mode."""
    if found.size == 0:
        return np.ones(true.size)
    return np.min(np.abs(found[None, :] - true[:, None]), axis=1) / true


def single_fits(path: Path, true: np.ndarray) -> list[dict]:
    prep = pipeline.prepare(read_frf(str(path)), Settings(), [])
    rows = []
    for n in ORDERS:
        for q in BLOCK_ROWS:
            t0 = time.perf_counter()
            model = subspace.identify(prep.z, prep.Hs, n, prep.T, q=q,
                                      weights=prep.line_weights, estimate_bd_=False)
            dt = time.perf_counter() - t0
            err = errors(in_band_poles(model.Ad, model.Cd, prep), true)
            sv = model.singular_values
            basis = subspace.row_basis(prep.z, q)
            rows.append({"n": n, "q": q, "basis": "monomial" if basis.monomial else "orthonormal",
                         "e6": int(np.sum(err < 1e-6)), "e3": int(np.sum(err < 1e-3)),
                         "e2": int(np.sum(err < 1e-2)), "median": float(np.median(err)),
                         "sv": float(sv[n - 1] / sv[0]), "time": dt})
            print(f"  single fit n={n} q={q}: {rows[-1]['e3']} within 1e-3, {dt:.2f} s",
                  file=sys.stderr)
    return rows


def monomial_coefficients(basis: subspace.RowBasis) -> np.ndarray:
    """``C`` with ``p_i(z) = sum_d C[i, d] z^d``, from the basis' recurrence."""
    q = basis.q
    C = np.zeros((q, q))
    C[0, 0] = basis.p0
    for j in range(q - 1):
        nxt = np.zeros(q)
        nxt[1:] = C[j, :-1]  # z p_j
        nxt -= basis.shift[: j + 1, j] @ C[: j + 1]
        C[j + 1] = nxt / basis.shift[j + 1, j]
    return C


def _congruence(C: np.ndarray, g: np.ndarray) -> np.ndarray:
    """``C g C^T`` over the two block-row axes of ``g`` (..., q, q, a, b)."""
    g = np.moveaxis(g, (-4, -3), (-2, -1))
    return np.moveaxis(C @ g @ C.T, (-2, -1), (-4, -3))


@dataclass
class CongruenceSums(subspace.GramSums):
    """Monomial (block-Toeplitz) sums whose blocks come out in the basis ``P = C W``."""

    C: np.ndarray = None  # type: ignore[assignment]

    def blocks(self, b: int | slice = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        tu, gyu, gyy = super().blocks(b)
        tu = self.C @ tu @ self.C.T
        return tu, _congruence(self.C, gyu), _congruence(self.C, gyy)


def congruence_gram_sums(z: np.ndarray):
    """A ``subspace.gram_sums`` for data points ``z`` that computes non-monomial bases as
    monomial power sums and a congruence (monomial bases as before)."""

    def gram_sums(basis: subspace.RowBasis, H: np.ndarray, weights=None, **kw):
        if basis.monomial:
            return DEFAULT_GRAM_SUMS(basis, H, weights, **kw)
        s = DEFAULT_GRAM_SUMS(subspace.monomial_basis(z, basis.q), H, weights, **kw)
        return CongruenceSums(uu=s.uu, yu=s.yu, yy=s.yy, q=s.q, kind="toeplitz",
                              C=monomial_coefficients(basis))

    return gram_sums


def gram_routes(path: Path, true: np.ndarray) -> dict:
    prep = pipeline.prepare(read_frf(str(path)), Settings(), [])
    q, ny = GRAM_Q, prep.Hs.shape[1]
    orth = subspace.orthonormal_basis(prep.z, q)
    mono = subspace.monomial_basis(prep.z, q)
    C = monomial_coefficients(orth)
    t0 = time.perf_counter()
    s_orth = subspace.gram_sums(orth, prep.Hs, prep.line_weights)
    t_orth = time.perf_counter() - t0
    t0 = time.perf_counter()
    s_mono = subspace.gram_sums(mono, prep.Hs, prep.line_weights)
    t_mono = time.perf_counter() - t0
    S_orth = subspace.schur_complement(s_orth)
    S_cong = subspace.schur_complement(CongruenceSums(
        uu=s_mono.uu, yu=s_mono.yu, yy=s_mono.yy, q=q, kind="toeplitz", C=C))
    out = {"q": q, "cond": subspace._monomial_gram_cond(prep.z, q), "t_orth": t_orth,
           "t_mono": t_mono, "rel": float(np.abs(S_cong - S_orth).max() / np.abs(S_orth).max())}
    for name, S in (("orth", S_orth), ("cong", S_cong)):
        O, _ = subspace.observability_from_schur(S, ORDERS[1])
        A, Cd = subspace.shift_invariance(O, ny, orth)
        err = errors(in_band_poles(A, Cd, prep), true)
        out[name] = {"e6": int(np.sum(err < 1e-6)), "e3": int(np.sum(err < 1e-3)),
                     "median": float(np.median(err))}
    return out


def pipeline_runs(path: Path, true: np.ndarray) -> list[dict]:
    data = read_frf(str(path))
    z = pipeline.prepare(data, Settings(), []).z  # the points the pipeline maps to
    default = subspace.block_rows
    rows = []
    runs = [(Q, False) for Q in PIPELINE_Q] + [(PIPELINE_Q[-1], True)]
    for Q, congruence in runs:
        def raised(n: int, ny: int, Q: int = Q) -> int:
            return default(n, ny) if ny <= 1 else max(default(n, ny), Q)

        sums = congruence_gram_sums(z) if congruence else DEFAULT_GRAM_SUMS
        with mock.patch.object(subspace, "block_rows", raised), \
                mock.patch.object(subspace, "gram_sums", sums):
            t0 = time.perf_counter()
            res = pipeline.identify(data, Settings(seed=0))
            dt = time.perf_counter() - t0
        phys = [m.frequency_hz for m in res.modes if m.physical]
        found, extra = match_modes(phys, list(true))
        rows.append({"Q": Q, "q": res.orders["block_rows"],
                     "basis": res.orders["basis"] + (" (congruence sums)" if congruence else ""),
                     "n0": res.orders["n0"], "n_ref": res.orders["reference"],
                     "physical": len(phys), "found": found, "extra": extra, "time": dt})
        print(f"  pipeline q>={Q} congruence={congruence}: {found} found, {extra} extra,"
              f" {dt:.1f} s", file=sys.stderr)
    return rows


def render(meta: dict, fits: dict, gram: dict, pipe: list[dict] | None) -> str:
    out = ["# Block rows for many outputs and many modes (case b)", ""]
    out += [f"* {k}: {v}" for k, v in meta.items()]
    out += ["", "## One identification against q", "",
            "| noise | n | q | row basis | true modes within 1e-6 / 1e-3 / 1e-2 (of 80) |"
            " median error | sigma_n / sigma_1 | s |", "|---|---:|---:|---|---|---:|---:|---:|"]
    for noise, rows in fits.items():
        for r in rows:
            out.append(f"| {noise} | {r['n']} | {r['q']} | {r['basis']} | {r['e6']} / {r['e3']}"
                       f" / {r['e2']} | {r['median']:.1e} | {r['sv']:.1e} | {r['time']:.2f} |")
    out += ["", f"## Replicate Gram sums at q = {gram['q']} (1 % noise, full data, order"
            f" {ORDERS[1]})", "",
            f"Monomial Gram condition number {gram['cond']:.1e}.", "",
            "| route | Gram sums s | true modes within 1e-6 / 1e-3 | median error |",
            "|---|---:|---|---:|",
            f"| orthonormal basis, q^2 products per line | {gram['t_orth']:.2f} |"
            f" {gram['orth']['e6']} / {gram['orth']['e3']} | {gram['orth']['median']:.1e} |",
            f"| monomial power sums + congruence | {gram['t_mono']:.2f} |"
            f" {gram['cong']['e6']} / {gram['cong']['e3']} | {gram['cong']['median']:.1e} |",
            "", f"Largest difference of the two Schur complements: {gram['rel']:.1e} of its"
            " largest entry."]
    if gram.get("noise_free"):
        nf = gram["noise_free"]
        out += ["", f"Noise-free file, same order: orthonormal route {nf['orth']['e6']} modes"
                f" within 1e-6, congruence {nf['cong']['e6']} (difference {nf['rel']:.1e})."]
    if pipe:
        out += ["", "## Pipeline with the block rows raised (1 % noise)", "",
                "| q at least | q | row basis | n0 | reference order | physical rows |"
                " true modes found (of 80) | physical rows matching no true mode | wall s |",
                "|---:|---:|---|---:|---:|---:|---:|---:|---:|"]
        for r in pipe:
            out.append(f"| {r['Q']} | {r['q']} | {r['basis']} | {r['n0']} | {r['n_ref']} |"
                       f" {r['physical']} | {r['found']} | {r['extra']} | {r['time']:.1f} |")
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--pipeline", action="store_true",
                    help="also run the whole pipeline with raised block rows (slow)")
    ap.add_argument("--out", metavar="FILE.md", help="also write the report to this file")
    args = ap.parse_args(argv)
    meta = {"automodal": f"git {git_state()}", "BLAS": blas_line(),
            "load average at start": load_average()}
    from threadpoolctl import threadpool_limits

    with tempfile.TemporaryDirectory() as tmp, threadpool_limits(1):
        files = {noise: simulate(Path(tmp), noise) for noise in (0.0, 0.01)}
        fits = {f"{noise:g}": single_fits(*files[noise]) for noise in files}
        gram = gram_routes(*files[0.01])
        nf = gram_routes(*files[0.0])
        gram["noise_free"] = {"orth": nf["orth"], "cong": nf["cong"], "rel": nf["rel"]}
        pipe = pipeline_runs(*files[0.01]) if args.pipeline else None
    meta["load average at end"] = load_average()
    text = render(meta, fits, gram, pipe)
    print(text)
    if args.out:
        Path(args.out).write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
