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
   chooses there) would make every Gram block a sum over ``q^2`` basis products instead of
   the ``2 q - 1`` power sums of the monomial basis; the package forms them in its product
   basis (``gram_sums``, kind ``"product"``, ``2 q - 1`` functions). Alternative measured
   here, from before the product basis: the monomial power sums turned into the
   orthonormal basis by the congruence with the basis' monomial coefficients (``P = C W``,
   so ``G_orth = C G_mono C^T`` block by block); its rounding error grows like
   ``eps cond(monomial Gram)``.
3. ``--pipeline`` (slow, about 3 minutes): ``pipeline.identify`` by default and with
   ``Settings.block_rows`` at each ``Q`` of ``PIPELINE_Q`` (at least ``Q`` block rows in
   every (sub-)band's reference and replicates): modes found, spurious physical rows,
   (sub-)bands, wall time. (Before ``Settings.block_rows`` and the product basis, this
   part patched ``block_rows`` and ran the largest ``Q`` once more with the congruence
   sums; part 2 keeps that comparison for one identification.)

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
    direct = subspace.orthonormal_basis(prep.z, q)
    direct.__dict__["products"] = None  # the q^2 basis products per line (sums_kind "direct")
    t0 = time.perf_counter()
    s_direct = subspace.gram_sums(direct, prep.Hs, prep.line_weights)
    t_direct = time.perf_counter() - t0
    S_orth = subspace.schur_complement(s_orth)
    S_cong = subspace.schur_complement(CongruenceSums(
        uu=s_mono.uu, yu=s_mono.yu, yy=s_mono.yy, q=q, kind="toeplitz", C=C))
    S_direct = subspace.schur_complement(s_direct)
    S_data = subspace.schur_from_data(orth, prep.Hs, prep.line_weights)
    scale = np.abs(S_data).max()
    out = {"q": q, "cond": subspace._monomial_gram_cond(prep.z, q), "t_orth": t_orth,
           "kind": s_orth.kind, "t_direct": t_direct,
           "t_mono": t_mono, "rel": float(np.abs(S_cong - S_orth).max() / np.abs(S_orth).max())}
    for name, S in (("orth", S_orth), ("direct", S_direct), ("cong", S_cong)):
        O, _ = subspace.observability_from_schur(S, ORDERS[1])
        A, Cd = subspace.shift_invariance(O, ny, orth)
        err = errors(in_band_poles(A, Cd, prep), true)
        out[name] = {"e6": int(np.sum(err < 1e-6)), "e3": int(np.sum(err < 1e-3)),
                     "median": float(np.median(err)),
                     "data": float(np.abs(S - S_data).max() / scale)}
    return out


def leaf_orders(orders: dict) -> list[dict]:
    """The orders of every band identified as one model (the sub-bands of a split band,
    and theirs when split again)."""
    parts = orders.get("sub_bands")
    return [o for p in parts for o in leaf_orders(p)] if parts else [orders]


def pipeline_runs(path: Path, true: np.ndarray) -> list[dict]:
    data = read_frf(str(path))
    rows = []
    for Q in (None, *PIPELINE_Q):
        t0 = time.perf_counter()
        res = pipeline.identify(data, Settings(seed=0, block_rows=Q))
        dt = time.perf_counter() - t0
        leaves = leaf_orders(res.orders)
        phys = [m.frequency_hz for m in res.modes if m.physical]
        found, extra = match_modes(phys, list(true))
        rows.append({"Q": "default" if Q is None else Q,
                     "q": ", ".join(str(o["block_rows"]) for o in leaves),
                     "bands": len(leaves), "n_ref": max(o["reference"] for o in leaves),
                     "physical": len(phys), "found": found, "extra": extra, "time": dt})
        print(f"  pipeline block_rows={Q}: {found} found, {extra} extra, {dt:.1f} s",
              file=sys.stderr)
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
            "| route | Gram sums s | true modes within 1e-6 / 1e-3 | median error |"
            " Schur complement's largest difference from the data matrix's |",
            "|---|---:|---|---:|---:|",
            f"| orthonormal basis, the package's sums ({gram['kind']}) | {gram['t_orth']:.2f} |"
            f" {gram['orth']['e6']} / {gram['orth']['e3']} | {gram['orth']['median']:.1e} |"
            f" {gram['orth']['data']:.1e} |",
            f"| orthonormal basis, q^2 products per line (direct) | {gram['t_direct']:.2f} |"
            f" {gram['direct']['e6']} / {gram['direct']['e3']} |"
            f" {gram['direct']['median']:.1e} | {gram['direct']['data']:.1e} |",
            f"| monomial power sums + congruence | {gram['t_mono']:.2f} |"
            f" {gram['cong']['e6']} / {gram['cong']['e3']} | {gram['cong']['median']:.1e} |"
            f" {gram['cong']['data']:.1e} |",
            "", f"Largest difference of the first and last Schur complements: {gram['rel']:.1e}"
            " of its largest entry (differences: of the largest entry of the data matrix's)."]
    if gram.get("noise_free"):
        nf = gram["noise_free"]
        out += ["", f"Noise-free file, same order: modes within 1e-6 by the package's sums"
                f" {nf['orth']['e6']} (difference from the data matrix's {nf['orth']['data']:.1e}),"
                f" the q^2 products {nf['direct']['e6']} ({nf['direct']['data']:.1e}), the"
                f" congruence {nf['cong']['e6']} ({nf['cong']['data']:.1e})."]
    if pipe:
        out += ["", "## Pipeline with the block rows raised (1 % noise, `Settings.block_rows`)",
                "", "| block_rows | q of each (sub-)band | (sub-)bands | largest reference order |"
                " physical rows | true modes found (of 80) | physical rows matching no true"
                " mode | wall s |", "|---|---|---:|---:|---:|---:|---:|---:|"]
        for r in pipe:
            out.append(f"| {r['Q']} | {r['q']} | {r['bands']} | {r['n_ref']} |"
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
        gram["noise_free"] = {"orth": nf["orth"], "direct": nf["direct"], "cong": nf["cong"],
                              "rel": nf["rel"]}
        pipe = pipeline_runs(*files[0.01]) if args.pipeline else None
    meta["load average at end"] = load_average()
    text = render(meta, fits, gram, pipe)
    print(text)
    if args.out:
        Path(args.out).write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
