"""Whitening by the noise model: line weights, channel scales and whitened statistics.

The subspace identification keeps its Kronecker structure only under a weight per line
(columns of the data matrices) and a scale per output channel (rows of ``C``). The noise
variance ``var[k, i, j]`` of :mod:`automodal.core.noise` is therefore approximated by a
separable model ``v_k a_i b_j`` (:func:`separable_variance`, a least-squares fit of the
log variance): ``1 / v_k`` becomes the line weight and ``sqrt(a_i)`` the output scale.
Weights and scales change how noise is weighed, never an exact model: noise-free data
are still identified exactly.

The statistics use the full variance: :func:`whitened_residual` (``2 |e|^2 / var`` summed,
chi-square distributed with two degrees of freedom per complex residual when the model
is right), :func:`mode_parameters` (the real parameters one mode adds to a model) and
:func:`mode_snr2` (a mode's matched-filter SNR squared: the energy of its own FRF term
against the noise).
"""

from __future__ import annotations

import numpy as np

from automodal.core.filters import running_median

MODEL_PRECISION = 1e-7
"""Relative accuracy of an identified model on exact data (about ``sqrt(eps)`` of the Gram
path, with margin): the order test adds ``(MODEL_PRECISION * rms_ij)^2`` to each entry's
variance, so noise-free data do not read rounding errors as unexplained structure."""


def separable_variance(variance: np.ndarray, iterations: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Fit ``log var[k, i, j] ~ log v_k + log a_i + log b_j`` (least squares, alternating).

    Parameters
    ----------
    variance : ndarray, shape (N, ny, nu)
        Noise variance per line and entry (> 0).
    iterations : int
        Alternating passes (the fit of a two-way additive model converges in one for
        complete data; a few more cost nothing).

    Returns
    -------
    line : ndarray, shape (N,)
        ``v_k``, normalised to geometric mean one.
    output : ndarray, shape (ny,)
        ``a_i`` with the input factors' geometric mean folded in (the variance of
        output ``i`` at a line of unit ``v_k``).
    """
    L = np.log(np.asarray(variance, dtype=float))
    lv = np.zeros(L.shape[0])
    la = np.zeros(L.shape[1])
    lb = np.zeros(L.shape[2])
    for _ in range(iterations):
        lv = np.mean(L - la[None, :, None] - lb[None, None, :], axis=(1, 2))
        la = np.mean(L - lv[:, None, None] - lb[None, None, :], axis=(0, 2))
        lb = np.mean(L - lv[:, None, None] - la[None, :, None], axis=(0, 1))
    shift = float(np.mean(lv))
    return np.exp(lv - shift), np.exp(la + shift + float(np.mean(lb)))


LINE_SMOOTHING = 0.1
"""Share of the lines over which the line variance is smoothed (running median of its
log) before it becomes a weight. The subspace projection is not a maximum-likelihood fit:
weighting each resonance down by its own height (proportional noise) hid modes from it
(calibration seeds 214: recall 0.898 and 20 false modes with per-line weights)."""


def whitening(
    variance: np.ndarray, smooth: float = LINE_SMOOTHING
) -> tuple[np.ndarray, np.ndarray]:
    """Line weights (mean one) and output scales that whiten the separable noise model.

    ``smooth`` (a share of the lines, 0 for none) smooths the line variance first (see
    :data:`LINE_SMOOTHING`): the weights then follow the noise's trend over the band.

    Returns
    -------
    line_weights : ndarray, shape (N,)
        ``1 / v_k`` normalised to mean one.
    scales : ndarray, shape (ny,)
        ``sqrt(a_i)``: dividing output ``i`` by it gives unit noise (up to the line weight).
    """
    v, a = separable_variance(variance)
    if smooth > 0 and v.size >= 3:
        size = max(3, int(round(smooth * v.size)) | 1)
        v = np.exp(running_median(np.log(v), size))
    w = 1.0 / v
    return w / np.mean(w), np.sqrt(a)


RANK_EDGE = 3.0
"""A direction of the outputs counts (:func:`output_rank`) when its singular value exceeds
this many times the largest that noise alone would give (the Marchenko-Pastur edge): below
it a direction is not told from the noise."""


def _lines_whitened(Hs: np.ndarray, variance: np.ndarray) -> tuple[np.ndarray, float]:
    """The FRF as ``ny x N nu``, each line divided by its own noise level (the root of its
    mean variance over the entries), and the noise std left (the root of the mean of the
    variances over their lines' levels: 1 within rounding)."""
    N, ny, nu = Hs.shape
    level = np.mean(variance, axis=(1, 2))
    X = (Hs / np.sqrt(level)[:, None, None]).transpose(1, 0, 2).reshape(ny, N * nu)
    return X, float(np.sqrt(np.mean(variance / level[:, None, None])))


def output_rank(Hs: np.ndarray, variance: np.ndarray) -> int:
    """Directions of the outputs that stand out of the noise: singular values of the FRF
    (``ny`` x ``N nu``), each line divided by its own noise level (the root of its mean
    variance over the entries), above :data:`RANK_EDGE` times the noise edge
    ``sigma (sqrt(N nu) + sqrt(ny))`` (``sigma`` = 1 up to the entries' spread).

    Each line is whitened exactly, not by the smoothed line weights of :func:`whitening`:
    with proportional noise the resonances then count as much as the valleys, which is how
    the identification's noise sees them (with the smoothed weights, 28 of 40 directions of
    an 8 x 10 grid's upper band were hidden behind its two strongest ones, or all 40 counted
    against the median variance).

    Parameters
    ----------
    Hs : ndarray, shape (N, ny, nu)
        Channel-scaled FRF.
    variance : ndarray, shape (N, ny, nu)
        Noise variance of ``Hs``'s entries.
    """
    N, ny, nu = Hs.shape
    X, sigma = _lines_whitened(Hs, variance)
    sv = np.linalg.svd(X, compute_uv=False)
    return int(np.count_nonzero(sv > RANK_EDGE * sigma * (np.sqrt(N * nu) + np.sqrt(ny))))


def principal_outputs(
    Hs: np.ndarray, variance: np.ndarray, n: int, q: int
) -> np.ndarray | None:
    """Real orthonormal output directions that hold the data's structure, for the
    bootstrap replicates of an ``n``-state model on ``q`` block rows; None when they are
    all the outputs.

    The FRF's lines are whitened as in :func:`output_rank` and stacked real
    (``[Re X, Im X]``, ``ny x 2 N nu``: real directions keep the FRF's conjugate symmetry,
    so the projected data are still those of a real system). The directions whose singular
    values exceed the noise edge ``sigma / sqrt(2) (sqrt(2 N nu) + sqrt(ny))`` carry the
    modes; twice as many are kept (a weak mode lifts a direction only a little above the
    bulk), and at least ``ceil(1.2 n / (q - 1))``, so that ``(q - 1) r >= 1.2 n`` holds for
    the ``r`` projected outputs as :func:`automodal.core.subspace.block_rows` asks (None for
    ``q < 2``).

    The replicates' shapes then vary only within these directions; the reported spread
    adds the others' share (:func:`automodal.core.summary.dropped_spread`).

    Parameters
    ----------
    Hs : ndarray, shape (N, ny, nu)
        Channel-scaled FRF.
    variance : ndarray, shape (N, ny, nu)
        Noise variance of ``Hs``'s entries.
    n, q : int
        Order and block rows of the replicates' models.

    Returns
    -------
    ndarray, shape (ny, r), real, orthonormal columns, or None
    """
    N, ny, nu = Hs.shape
    if int(q) < 2:  # one block row: no shift invariance to keep the rank argument for
        return None
    X, sigma = _lines_whitened(Hs, variance)
    G = X.real @ X.real.T + X.imag @ X.imag.T  # [Re X, Im X] times its transpose
    w, V = np.linalg.eigh(G)
    w, V = w[::-1], V[:, ::-1]
    edge = sigma / np.sqrt(2.0) * (np.sqrt(2.0 * N * nu) + np.sqrt(ny))
    above = int(np.count_nonzero(np.sqrt(np.clip(w, 0.0, None)) > edge))
    r = max(2 * above, int(np.ceil(1.2 * n / max(int(q) - 1, 1))), 1)
    if r >= ny:
        return None
    return np.ascontiguousarray(V[:, :r])


def whitened_residual(H_model: np.ndarray, H: np.ndarray, variance: np.ndarray) -> float:
    """``sum 2 |H_model - H|^2 / var`` over lines and entries: chi-square with ``2 N ny nu``
    degrees of freedom (less the fitted parameters) when the model is right."""
    return float(2.0 * np.sum(np.abs(H_model - H) ** 2 / variance))


def test_variance(H: np.ndarray, variance: np.ndarray) -> np.ndarray:
    """The variance the order test uses: the noise plus the model's own precision
    (:data:`MODEL_PRECISION` of each entry's RMS)."""
    rms2 = np.mean(np.abs(H) ** 2, axis=0, keepdims=True)
    return variance + (MODEL_PRECISION**2) * rms2


def mode_parameters(ny: int, nu: int) -> int:
    """Real parameters one mode (a pole pair) adds to a model: its pole (2), a complex
    shape and a complex participation (``2 (ny + nu)``), less a complex scale (2)."""
    return 2 * (int(ny) + int(nu))


def dispersion(H_model: np.ndarray, H: np.ndarray, variance: np.ndarray, n_states: int) -> float:
    """``max(1, chi2 / dof)``: how much more than the noise a model leaves unexplained.

    ``chi2`` is :func:`whitened_residual` of the model and ``dof`` its degrees of freedom,
    ``2 N ny nu`` less the model's real parameters (``n_states / 2`` modes of
    :func:`mode_parameters` each). At high SNR a subspace model's residual is dominated by
    its own bias rather than the noise (measured up to 30-1000 times the noise on the
    calibration files); spurious modes then fit that residual, so SNRs and resampled noise
    are scaled by this factor (a quasi-likelihood dispersion).
    """
    N, ny, nu = H.shape
    dof = 2.0 * N * ny * nu - n_states / 2.0 * mode_parameters(ny, nu)
    if dof <= 0:
        return 1.0
    return max(1.0, whitened_residual(H_model, H, variance) / dof)


SNR_MAX_LINES = 1000
"""Lines on which :func:`mode_snr2` forms its Gram matrix (chosen by
:func:`quadrature_lines`, each weighted by the lines it stands for)."""

SNR_PART_BYTES = 4 * 2**20
"""Size of the columns of one part of the lines in :func:`mode_snr2`, whose products it
forms apart (on the free cores) and adds in order: set by the sizes alone, so the sum does
not depend on the workers."""


def quadrature_lines(
    z: np.ndarray, poles: np.ndarray, budget: int
) -> tuple[np.ndarray, np.ndarray]:
    """At most about ``budget`` of the lines ``z``, and weights, for sums over lines of
    functions of the modal terms ``1 / (z - mu)``.

    A modal term varies over a line distance ``s_k = min |z_k - mu| / h_k`` (``h_k`` the
    spacing of the lines at ``z_k``): within a few lines of a lightly damped pole it
    changes from line to line, far from every pole it is smooth. The lines are taken with
    density ``d_k = min(1, kappa / s_k)`` (``kappa`` so that they number ``budget``, by
    bisection), by systematic sampling of the cumulative density, each with weight
    ``1 / d_k``: every line near a pole, sparse lines between. Even spread lines missed the
    peak of a mode narrower than their step: the SNR^2 of a real 1518 Hz mode (half-power
    bandwidth 0.6 of a line spacing, 3072 lines, one in three taken) came out at half its
    value over all lines on one impact record and at twice it on another.

    Parameters
    ----------
    z : ndarray, shape (N,)
        Lines (ordered along the unit circle).
    poles : ndarray
        Poles of the terms (the conjugates are added).
    budget : int
        Lines wanted (all lines when ``N <= budget``).

    Returns
    -------
    index : ndarray of int
        Chosen lines, increasing.
    weight : ndarray
        Lines each stands for (1 where every line is taken).
    """
    z = np.asarray(z)
    N = z.size
    if N <= budget or np.size(poles) == 0:
        return np.arange(N), np.ones(N)
    mu = np.concatenate([np.ravel(poles), np.conj(np.ravel(poles))])
    gap = np.abs(np.diff(z))
    h = np.empty(N)
    h[0], h[-1] = gap[0], gap[-1]
    h[1:-1] = 0.5 * (gap[:-1] + gap[1:])
    dist = np.full(N, np.inf)
    for m in mu:  # pole by pole: memory of the lines only (not lines x poles)
        np.minimum(dist, np.abs(z - m), out=dist)
    s = np.maximum(dist / np.maximum(h, np.finfo(float).tiny), np.finfo(float).tiny)

    def count(kappa: float) -> float:
        return float(np.sum(np.minimum(1.0, kappa / s)))

    lo, hi = 0.0, float(np.max(s))
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if count(mid) < budget else (lo, mid)
    d = np.minimum(1.0, hi / s)
    steps = np.floor(np.cumsum(d) + 0.5)
    index = np.flatnonzero(np.diff(np.concatenate([[0.0], steps])) > 0)
    return index, 1.0 / d[index]


def mode_snr2(
    modal, z: np.ndarray, variance: np.ndarray, max_lines: int = SNR_MAX_LINES,
    jobs: int | None = 1,
) -> np.ndarray:
    """Conditional matched-filter SNR squared of each oscillatory mode of a modal model.

    How much the whitened residual (units of :func:`whitened_residual`) would grow if the
    mode were left out and the other modes' residues refitted: ``1 / [(G^T G)^-1]`` for
    the mode's own term in the real regression on all modes' terms (each mode a complex
    residue: two real columns, its term and ``i`` times its anti-symmetric part). For an
    isolated mode this is ``sum 2 |H_mode|^2 / var``; modes of an over-fitted model that
    cancel each other (large terms, small sum) get what they really explain. A mode that
    only fits noise explains about :func:`mode_parameters` of it.

    Parameters
    ----------
    modal : ModalModel
        The model (with ``B``), in the units of ``variance``.
    z : ndarray, shape (N,)
        Lines on the unit circle.
    variance : ndarray, shape (N, ny, nu)
        Noise variance in the model's units.
    max_lines : int
        Lines the sums are taken over (:func:`quadrature_lines`, weighted).
    jobs : int or None
        Worker threads (:func:`automodal.core.parallel.freeing_map`) for the Gram
        matrix's parts (the lines split by :data:`SNR_PART_BYTES`, added in order): the
        result does not depend on them. A 38-output dense grid's sub-band (seed 459 f_17,
        70 modes) spent 0.8 s here on one core, the other idle.

    Returns
    -------
    ndarray, shape (number of oscillatory modes,)
    """
    from automodal.core.parallel import freeing_map

    sel = modal.oscillatory
    if sel.size == 0 or modal.B is None:
        return np.zeros(sel.size)
    sub, weight = quadrature_lines(z, modal.mu[sel], max_lines)
    zs = z[sub]
    n_lines = zs.size
    # real inner products of 2 |x|^2 / var, each line standing for ``weight`` lines
    w = np.sqrt(2.0 * weight[:, None, None] / variance[sub]).reshape(
        n_lines, variance.shape[1] * variance.shape[2])
    CV = (modal.C @ modal.V)[:, sel]
    L = modal.modal_inputs[sel]
    mu = modal.mu[sel]
    m = sel.size
    # The columns of mode a: its term P / (z - mu) and its conjugate's conj(P) / (z - conj
    # mu), P = (C v) l^T over the entries, give s (their sum) and i d (i times their
    # difference), each as its real and then its imaginary part over (line, entry). With
    # A = 1 / (z - mu) and B = 1 / (z - conj mu) every one of these four real blocks is a
    # sum of two outer products of line functions with Re P and Im P:
    #   Re s = (Re A + Re B) Re P - (Im A - Im B) Im P
    #   Im s = (Im A + Im B) Re P + (Re A - Re B) Im P
    #   Re(i d) = -Im d = -(Im A - Im B) Re P - (Re A + Re B) Im P
    #   Im(i d) = Re d = (Re A - Re B) Re P - (Im A + Im B) Im P
    A = 1.0 / (zs[None, :] - mu[:, None])  # (m, lines)
    B = 1.0 / (zs[None, :] - np.conj(mu)[:, None])
    sr, dr = A.real + B.real, A.real - B.real
    si, di = A.imag + B.imag, A.imag - B.imag
    X = np.stack([np.stack([sr, -di], axis=-1), np.stack([si, dr], axis=-1),
                  np.stack([-di, -sr], axis=-1), np.stack([dr, -si], axis=-1)], axis=1)
    P = (CV.T[:, :, None] * L[:, None, :]).reshape(m, -1)  # (m, entries), as w's
    PP = np.stack([P.real, P.imag], axis=1)[:, None]  # (m, 1, 2, entries)
    # the Gram matrix summed over parts of a few lines each (in order, whatever the
    # workers), so that no part's columns outgrow the caches: all the columns at once
    # (2 m x 2 lines entries, 240 MB for 91 modes of 27 x 3 entries) cost more in first
    # touches of fresh memory than in arithmetic
    lines_per_part = max(1, SNR_PART_BYTES // (8 * 4 * m * w.shape[1]))
    bounds = np.append(np.arange(0, n_lines, lines_per_part), n_lines)

    def part(k: int) -> np.ndarray:
        lo, hi = bounds[k], bounds[k + 1]
        block = np.matmul(X[:, :, lo:hi], PP)  # (m, 4, lines, entries)
        block *= w[None, None, lo:hi]
        c = block.reshape(2 * m, -1)  # mode a: rows 2a (s) and 2a + 1 (i d)
        return c @ c.T

    with freeing_map(jobs, bounds.size - 1, 16.0 * m * m * w.size) as (_, pmap):
        gram = np.zeros((2 * m, 2 * m))
        for g in pmap(part, range(bounds.size - 1)):
            gram += g
    try:
        inv = np.linalg.pinv(gram, rcond=1e-12, hermitian=True)
    except np.linalg.LinAlgError:
        return np.diag(gram)[0::2]
    out = np.empty(m)
    for i in range(m):
        block = inv[2 * i : 2 * i + 2, 2 * i : 2 * i + 2]
        try:
            out[i] = np.linalg.inv(block)[0, 0]
        except np.linalg.LinAlgError:
            out[i] = 0.0
    return np.maximum(out, 0.0)
