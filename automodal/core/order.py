"""Model order: the misfit scan and the choice of the orders the pipeline uses.

:func:`select_orders` is the pipeline's one call: the largest order the data allow
(:func:`order_limit`, bootstrap replicates included), the staged misfit scan
(:func:`scan`, sized by :func:`count_peaks`), ``n0`` where the misfit reaches its floor
(:func:`order_at_floor`) and the excessive reference order (:func:`excessive_order`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from automodal.core import subspace
from automodal.core.filters import running_max, running_min
from automodal.core.magnitude import (
    log_magnitude,
    mean_magnitude,
    peak_threshold,
    roughness,
)
from automodal.core.parallel import freeing_map
from automodal.core.whitening import (
    MODEL_PRECISION,
    mode_parameters,
    test_variance,
    whitened_residual,
)
from automodal.errors import InputError

BOOTSTRAP_LINE_FRACTION = 0.6
"""Unique lines in a frequency-line replicate are about 63 % of all lines: the order is
limited so that a replicate still has enough (``2 * 0.6 N nu >= q (nu + ny)``)."""

MAX_SCAN_ORDER = 240
"""Highest order of the automatic misfit scan (``--order`` can set a lower limit)."""

MAX_REFERENCE_ORDER = 320
"""Highest automatic reference order: each replicate costs ``O(n^3)``, and at 320 states 100
replicates take several seconds on two cores. ``--order`` can raise it."""


def log_misfit(H_model: np.ndarray, H: np.ndarray) -> float:
    """``MC = mean |log|H_model| - log|H||`` over lines and channels (zeros skipped)."""
    a, b = np.abs(H_model), np.abs(H)
    ok = (a > 0) & (b > 0)
    if not ok.any():
        return float("inf")
    return float(np.mean(np.abs(np.log(a[ok]) - np.log(b[ok]))))


def order_at_floor(
    orders: np.ndarray, misfit: np.ndarray, factor: float = 1.5, fraction: float = 0.05
) -> int:
    """``n0``: the first order at which the misfit has reached its floor.

    The floor is the median misfit over the upper half of the scanned orders, where only
    noise is left to fit. An order has reached it when its misfit is within ``factor`` of
    the floor **and** within ``fraction`` of the whole fall (largest misfit minus floor)
    above it; the second condition matters when noise keeps the floor high, as with many
    small FRF entries.

    This replaces the "last clear drop" rule of ``method.md`` (``MC(n-2) / MC(n) >= 2``):
    at 5 % noise the drop at the true order was only 1.5x, and noise alone made 2x drops
    at high orders (10-DOF chain: the drop rule gave n0 = 2 or 48 for a true 20; this rule
    20 or 22). On an 80-mode, 40-output grid the log misfit fell only from 3.4 to a floor
    of 1.0 (tiny entries stay noisy), and the factor alone gave n0 = 60 for a true 160;
    with the fraction it gives 140.

    Parameters
    ----------
    orders : ndarray
        Increasing model orders.
    misfit : ndarray
        ``MC`` at each order.
    factor : float
        Ratio to the floor that counts as reached.
    fraction : float
        Share of the whole fall that may remain.
    """
    orders = np.asarray(orders)
    misfit = np.asarray(misfit, dtype=float)
    ok = np.isfinite(misfit)
    if not ok.any():
        return int(orders[0])
    # the best misfit reached so far: a truncated model of higher order may fit worse in
    # the log sense (measured on ambient half spectra, where the curve rose again after its
    # minimum and the raw floor sat at 2x the minimum)
    misfit = np.where(ok, misfit, np.inf)
    misfit = np.minimum.accumulate(misfit)
    ok = np.isfinite(misfit)
    floor = float(np.median(misfit[ok][ok.sum() // 2 :]))
    top = float(np.max(misfit[ok]))
    # a misfit at the identification's own precision is the floor whatever the others:
    # on noise-free data rounding (1e-14 against 1e-10) must not decide the order
    limit = max(min(factor * floor, floor + fraction * (top - floor)), MODEL_PRECISION)
    reached = np.flatnonzero(ok & (misfit <= limit))
    return int(orders[reached[0]]) if reached.size else int(orders[-1])


def excessive_order(n0: int, n_max: int, factor: float = 3.0) -> int:
    """The reference ("excessive") order ``max(factor n0, n0 + 20)``, even, at most
    ``n_max`` (``factor`` 3 after the misfit floor, which stops short of the true order;
    :data:`SIGNIFICANT_EXCESS` after the significance test, which does not)."""
    n_hi = max(int(round(factor * int(n0))), int(n0) + 20)
    n_hi = min(n_hi, int(n_max))
    return max(2, n_hi - n_hi % 2)


SCAN_LINES = 400
"""Lines (evenly spread) on which the scan fits ``B``, ``D`` and evaluates its misfits."""


def misfit_scan(
    z: np.ndarray,
    H: np.ndarray,
    orders: np.ndarray,
    basis,
    max_lines: int = SCAN_LINES,
    weights: np.ndarray | None = None,
    stop_after: int | None = None,
    patience: int = 24,
    variance: np.ndarray | None = None,
    params: int = 0,
    z_alarm: float = 0.0,
    models: list[tuple[int, np.ndarray, np.ndarray]] | None = None,
    jobs: int | None = None,
    schur: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray] | tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Misfit ``MC(n)`` of the models of each order, from one observability subspace.

    All orders share the block rows of ``basis``, so the projection is computed once and
    the model of order ``n`` comes from its ``n`` leading directions. ``B`` and ``D`` are
    fitted, and the misfit evaluated, on at most ``max_lines`` evenly spread lines.

    Parameters
    ----------
    z : ndarray, shape (N,)
        Data points on the unit circle.
    H : ndarray, shape (N, ny, nu)
        FRF (scaled).
    orders : ndarray of int
        Orders to evaluate, increasing.
    basis : RowBasis
        Row basis (its ``q`` must hold the largest order).
    max_lines : int
        Lines used for the fit of ``B``, ``D`` and the misfit.
    weights : ndarray, optional
        Line weights of the projection and of the ``B``, ``D`` fit.
    stop_after : int, optional
        From this order on, stop once the best misfit has not improved by 10 % over the
        last ``patience`` states (the floor is reached; the scan need not go further);
        with ``variance``: once, besides, no order of the last ``patience`` states is
        significant (:func:`significant_order`). The whitened residual alone stopped too
        early where low-order models fit the whitened data worse than the smallest one: a
        dense grid's sub-band starting at 18.45 Hz rose from 0.89 to 4 times the residual
        of order 2 by order 28 and stopped at 52 with ``n0 = 4``, while its misfit still
        fell; from 19.0 Hz it fell to 0.17 times by order 80.
    patience : int
        See ``stop_after``.
    variance : ndarray, shape (N, ny, nu), optional
        Noise variance of ``H``'s entries: the whitened residual
        (:func:`automodal.core.whitening.whitened_residual`) is then returned too.
    params, z_alarm : int, float
        Parameters per mode and the false-alarm quantile of the order test (with
        ``variance``, for the early stop).
    models : list, optional
        When given, ``(n, mu, C V)`` of every evaluated order is appended to it (the
        eigenvalues of ``A`` and the output-side eigenvectors: the poles and shapes of a
        stabilization diagram, :mod:`automodal.core.stabilization`).
    jobs : int or None
        Worker threads for the orders (:func:`automodal.core.parallel.freeing_map`; None:
        the cores free as the scan goes); the result does not depend on it. On one core
        the whole band of an 8 x 10 grid (40 outputs, 3 inputs, 3000 lines) was scanned
        alone for 3.6 s before it was split, the other core idle.
    schur : ndarray, optional
        :func:`automodal.core.subspace.single_schur` of ``basis``, ``H`` and ``weights``,
        when the caller has it already.

    Returns
    -------
    orders : ndarray
        The orders evaluated (a prefix of ``orders``).
    misfit : ndarray
        ``MC`` per order.
    chi2 : ndarray
        With ``variance`` only: the whitened residual per order (on the lines of the fit).
    """
    N, ny, _ = H.shape
    O, _, _ = subspace.observability(basis, H, int(np.max(orders)), weights=weights, jobs=jobs,
                                     schur=schur)
    sub = np.unique(np.linspace(0, N - 1, min(N, max_lines)).round().astype(int))
    w_sub = None if weights is None else weights[sub]
    var_sub = None if variance is None else variance[sub]

    def evaluate(n: int) -> tuple[float, float, tuple[int, np.ndarray, np.ndarray]]:
        A, _ = subspace.shift_invariance(O[:, :n], ny, basis)
        lam, V = np.linalg.eig(A)  # one eigendecomposition for B/D, the response, the poles
        CV, C = subspace.output_matrix(O[:, :n], lam, V, basis, ny)
        B, D = subspace.estimate_bd(z[sub], H[sub], A, C, weights=w_sub, eigen=(lam, V))
        Hm = D[None] + subspace.modal_sum(CV, lam, np.linalg.solve(V, B), z[sub])
        residual = np.nan if var_sub is None else whitened_residual(Hm, H[sub], var_sub)
        return log_misfit(Hm, H[sub]), residual, (int(n), lam, CV)

    out: list[float] = []
    chi2: list[float] = []
    # the orders are independent: a batch of them at a time on the free cores, taken in
    # order (the stop rule sees each as the sequential loop would; a batch's orders past
    # the stop are dropped), so the result does not depend on the workers
    per_order = 8.0 * min(N, max_lines) * ny * H.shape[2] * float(np.max(orders)) ** 2
    with freeing_map(jobs, len(orders), per_order * len(orders)) as (n_jobs, pmap):
        for first in range(0, len(orders), n_jobs):
            stop = False
            batch = orders[first: first + n_jobs]
            for i, (misfit, residual, model) in enumerate(pmap(evaluate, batch), first):
                n = int(orders[i])
                if models is not None:
                    models.append(model)
                out.append(misfit)
                if var_sub is None:
                    stop = (stop_after is not None and n >= stop_after
                            and _settled(orders[: i + 1], out, patience))
                else:
                    chi2.append(residual)
                    stop = _noise_settled(orders[: i + 1], out, chi2, stop_after, patience,
                                          params, z_alarm, sub.size, ny, H.shape[2])
                if stop:
                    break
            if stop:
                break
    done = np.asarray(orders[: len(out)])
    if var_sub is None:
        return done, np.asarray(out)
    return done, np.asarray(out), np.asarray(chi2)


def _noise_settled(
    orders: np.ndarray, out: list[float], chi2: list[float], stop_after: int | None,
    patience: int, params: int, z_alarm: float, n_lines: int, ny: int, nu: int,
) -> bool:
    """The stop rule of :func:`misfit_scan` with a noise model, after its last order."""
    n = int(orders[-1])
    if stop_after is None or n < stop_after or n - orders[0] < patience:
        return False
    n_sig = significant_order(orders, np.asarray(chi2), params, z_alarm, ORDER_TOLERANCE)
    return n_sig <= n - patience and (
        plateaued(orders, out, patience)
        or fits_noise(chi2[list(orders).index(n_sig)], n_lines, ny, nu, n_sig))


def significant_order(
    orders: np.ndarray,
    chi2: np.ndarray,
    params: int,
    z_alarm: float,
    tolerance: float = 0.0,
) -> int:
    """The smallest order that no higher order improves on significantly.

    Adding ``k = (m - n) / 2`` modes that only fit noise lowers the whitened residual by
    about a chi-square with ``k p`` degrees of freedom (``p`` = ``params``, the real
    parameters of one mode): mean ``k p``, variance ``2 k p``. Order ``n`` is enough when
    for every scanned ``m > n`` the best residual up to ``m`` is not below the one at
    ``n`` by more than ``k p + z_alarm sqrt(2 k p) + tolerance * chi2(n)``. Only
    differences of the residual enter, so the absolute noise level matters little. The
    relative ``tolerance`` covers what the noise does not explain: a subspace model is not
    the least-squares one, and at high SNR its residual (dominated by that bias) wanders
    by several per cent from order to order.

    Parameters
    ----------
    orders : ndarray of int
        Increasing scanned orders.
    chi2 : ndarray
        Whitened residual at each order (non-finite values are skipped).
    params : int
        Real parameters per mode (:func:`automodal.core.whitening.mode_parameters`).
    z_alarm : float
        Quantile of the standard normal for the false-alarm probability of one test.
    tolerance : float
        Share of the residual at ``n`` that a gain must exceed as well.
    """
    orders = np.asarray(orders)
    c = np.asarray(chi2, dtype=float)
    c = np.minimum.accumulate(np.where(np.isfinite(c), c, np.inf))
    for i, n in enumerate(orders):
        if not np.isfinite(c[i]):
            continue
        k = (orders[i + 1 :] - n) / 2.0 * params
        gain = c[i] - c[i + 1 :]
        if not np.any(gain > k + z_alarm * np.sqrt(2.0 * k) + tolerance * c[i]):
            return int(n)
    return int(orders[-1])


def still_falling(orders: np.ndarray, misfit, share: float = 0.05) -> bool:
    """Whether the best misfit fell by more than ``share`` of its whole fall over the last
    third of the scanned orders (then a scan should go further).

    On an 80-mode, 40-output grid the misfit fell steadily (3.4 to 1.6 by order 84, 14 %
    of the fall in the last third) while improving by less than 10 % per 24 states, which
    :func:`plateaued` read as a floor; the true order was 160.
    """
    orders = np.asarray(orders)
    misfit = _at_least_precision(misfit)
    best = np.minimum.accumulate(np.where(np.isfinite(misfit), misfit, np.inf))
    if orders.size < 3 or not np.isfinite(best[-1]):
        return False
    total = float(np.max(best[np.isfinite(best)]) - best[-1])
    cut = orders[-1] - (orders[-1] - orders[0]) / 3.0
    before = best[orders <= cut][-1]
    return bool(total > 0 and (before - best[-1]) > share * total)


def _settled(orders: np.ndarray, misfit, patience: int) -> bool:
    """Whether a scan without a noise model may stop: the misfit has plateaued and is no
    longer falling (the rule that extends a stage, :func:`still_falling`). With a noise
    model the significance test stops it: a misfit still falling there is noise being
    fitted (a 6-DOF chain whose upper band is noise scanned to 240 states)."""
    return plateaued(orders, misfit, patience) and not still_falling(orders, misfit)


def _at_least_precision(misfit) -> np.ndarray:
    """Misfits with those below :data:`MODEL_PRECISION` read as that precision: below the
    identification's own precision a misfit is rounding (see :func:`plateaued`)."""
    return np.maximum(np.asarray(misfit, dtype=float), MODEL_PRECISION)


def plateaued(orders: np.ndarray, misfit, patience: int = 24) -> bool:
    """Whether the best misfit has not improved by 10 % over the last ``patience`` states.

    Misfits below the identification's own precision (:data:`MODEL_PRECISION`) count as
    that precision: on noise-free data they are rounding, and which of two such numbers is
    smaller depends on the machine's BLAS kernels (a two-mode SISO scan at misfits of
    1.3e-14 and 7.2e-15 went on past its plateau on an AMD EPYC, not on the machine its
    test was written on).
    """
    orders = np.asarray(orders)
    misfit = _at_least_precision(misfit)
    past = orders <= orders[-1] - patience
    if not past.any() or past.all():
        return False
    return bool(np.min(misfit[~past]) > 0.9 * np.min(misfit[past]))


# ---------------------------------------------------------------------------------------
# The pipeline's choice of orders
# ---------------------------------------------------------------------------------------


def block_row_budget(n_lines: int, ny: int, nu: int) -> int:
    """Most block rows a frequency-line replicate's lines allow: ``q (nu + ny) <= 2 *
    BOOTSTRAP_LINE_FRACTION * n_lines * nu`` (the projection needs at least as many real
    columns as rows)."""
    return int(2.0 * BOOTSTRAP_LINE_FRACTION * n_lines * nu) // (ny + nu)


def order_limit(n_lines: int, ny: int, nu: int) -> int:
    """Largest even order the data allow, bootstrap replicates included (0 if none)."""
    rows = block_row_budget(n_lines, ny, nu)
    n = 2
    while True:
        nxt = n + 2
        if subspace.block_rows(nxt, ny) > rows or nxt > 2000:
            return n if subspace.block_rows(n, ny) <= rows else 0
        n = nxt


def lines_needed(n: int, ny: int, nu: int) -> int:
    """Fewest frequency lines for which :func:`order_limit` allows order ``n``."""
    return _lines_for_rows(subspace.block_rows(n, ny), ny, nu)


def _lines_for_rows(q: int, ny: int, nu: int) -> int:
    """Fewest frequency lines whose replicates hold ``q`` block rows
    (:func:`block_row_budget` inverted)."""
    return int(np.ceil(q * (nu + ny) / (2.0 * BOOTSTRAP_LINE_FRACTION * nu)))


def lines_for_orders(ny: int, nu: int, max_order: int | None = None) -> int:
    """Fewest frequency lines with which every automatic order is open to a band of ``ny``
    outputs and ``nu`` inputs: a replicate still holds the order scan's block rows
    (:func:`automodal.core.subspace.scan_block_rows`) at the highest reference order
    (:data:`MAX_REFERENCE_ORDER`, or ``max_order`` when given), the rows of the second
    analysis; in either orientation, as reciprocity may swap outputs and inputs. A band
    reduced to fewer lines (:mod:`automodal.core.line_compression`) could lose orders the
    data need."""
    n = MAX_REFERENCE_ORDER if max_order is None else max(int(max_order), 2)
    return max(_lines_for_rows(subspace.scan_block_rows(n, a), a, b)
               for a, b in ((ny, nu), (nu, ny)))


def count_peaks(H: np.ndarray, window: int = 5, variance: np.ndarray | None = None) -> int:
    """Resonance-like peaks of the mean magnitude over channels (sizes the order scan):
    the number of :func:`peak_lines`."""
    return int(peak_lines(H, window, variance).size)


PEAK_NOISE_SIGMAS = 6.0
"""With a noise model, a peak must stand this many standard deviations of the mean
magnitude's noise above the lowest value on *each* side (within the rise's window). Over
pure noise the largest of 11 lines and the smallest of 45 differ by about 4 of them, and
by 6 about once in a thousand windows."""


def peak_lines(
    H: np.ndarray, window: int = 5, variance: np.ndarray | None = None
) -> np.ndarray:
    """Lines of the resonance-like peaks of the mean magnitude over channels.

    A line counts when it is the largest within ``window`` lines on either side and stands
    above the smallest value there by more than the threshold: ``max(0.5, 6 s)`` on the
    natural-log scale, with ``s`` the line-to-line roughness of the log magnitude (robust:
    median absolute second difference; :mod:`automodal.core.magnitude`). On pure noise
    the roughness is large and few "peaks" count, which keeps the scan short.

    With ``variance`` (the noise variance of ``H``'s entries), a peak must also rise above
    the lowest value on *each* side within the same reach by :data:`PEAK_NOISE_SIGMAS`
    standard deviations of the mean magnitude's noise: a wiggle of an additive noise floor
    is a local maximum that rises on one side only (towards the flank it sits on), or by no
    more than the noise. On a 6000-line SISO accelerance with 10 % additive noise and 4
    modes the first rule alone counted 60 peaks and sized the scan at 160 states.

    Returns
    -------
    ndarray of int
        Increasing line indices.
    """
    mag = mean_magnitude(H)
    if not np.any(mag > 0):
        return np.zeros(0, dtype=int)
    logm = log_magnitude(mag, 1e-12)
    thr = peak_threshold(roughness(logm))
    size = 2 * window + 1
    is_max = logm >= running_max(logm, size)
    rise = logm - running_min(logm, 8 * size)
    lines = np.flatnonzero(is_max & (rise > thr))
    if variance is None or lines.size == 0:
        return lines
    # noise std of the mean of |H| over the entries: var(|h|) is at most var(h) / 2
    n_entries = H.shape[1] * H.shape[2]
    sigma = np.sqrt(0.5 * np.sum(variance[lines], axis=(1, 2))) / n_entries
    reach = 4 * size
    left = np.array([mag[max(0, k - reach) : k + 1].min() for k in lines])
    right = np.array([mag[k : k + reach + 1].min() for k in lines])
    prominence = mag[lines] - np.maximum(left, right)
    return lines[prominence > PEAK_NOISE_SIGMAS * sigma]


def first_stage(n_peaks: int) -> int:
    """Order of the misfit scan's first stage for ``n_peaks`` resonance peaks (two states a
    peak and 40 to spare, at least 60)."""
    return max(2 * int(n_peaks) + 40, 60)


def scan_orders(n_scan: int) -> np.ndarray:
    """Orders of the misfit scan: every even order to 60, then steps of 4, then of 8 above 120."""
    orders = [n for n in range(2, min(n_scan, 60) + 1, 2)]
    orders += [n for n in range(64, min(n_scan, 120) + 1, 4)]
    orders += [n for n in range(128, n_scan + 1, 8)]
    return np.array(orders, dtype=int)


def scan(
    z: np.ndarray,
    H: np.ndarray,
    weights: np.ndarray,
    n_max: int,
    n_peaks: int,
    variance: np.ndarray | None = None,
    params: int = 0,
    z_alarm: float = 0.0,
    models: list[tuple[int, np.ndarray, np.ndarray]] | None = None,
    split_above: int | None = None,
    stages: dict | None = None,
    jobs: int | None = None,
):
    """The misfit scan, in stages.

    Up to ``max(2 n_peaks + 40, 60)`` states first, and twice as far (with the block rows
    that order needs) while the misfit still falls at the end of a stage
    (:func:`still_falling`), up to ``n_max``. Small systems pay only for a small
    projection; systems with many overlapping modes (80 modes, 22 visible peaks) still
    reach their order.

    With ``variance`` (the noise of ``H``), a stage is extended while its significant
    order (:func:`significant_order`) lies in the last third of it or the misfit still
    falls (:func:`still_falling`), and the whitened residual is returned too. ``models``
    (optional) receives ``(n, mu, C V)`` of every order of the last stage (see
    :func:`misfit_scan`).

    ``split_above`` (optional): once a stage's ``n0`` (:func:`order_at_floor`, or the
    significant order) reaches it, the scan ends there: the caller will split the band
    anyway (:mod:`automodal.core.sub_bands`), and a larger stage would only cost. A dense
    grid of 6000 lines and 24 outputs went on to a stage of 240 states (4.7 of its 7 s of
    scanning) before being split in two.

    ``stages`` (optional), a dict, keeps each stage's scan, keyed by the stage and whether
    ``variance`` was given: a later scan of the same data with the same dict reuses them
    (a scan that ``split_above`` ended early, redone without it when the band is not split
    after all, goes through the same stages first; a dense grid's sub-band, seed 459 f_17,
    spent 0.9 of its 2.1 s of rescanning on them). ``jobs``: worker threads of each stage
    (:func:`misfit_scan`).

    With ``variance``, each stage also counts the directions its projection shows above
    the noise (:func:`noise_directions`), for :func:`select_orders` to cap the last
    stage's order with. The stages go on as the significant order alone says: capped there
    too, a first stage's order stood where the larger stage it no longer led to would have
    found a smaller one (family seed 503 f_09: 28 states against 10).

    Returns
    -------
    orders, misfit : ndarray
        As :func:`misfit_scan` gives them for the last stage.
    chi2 : ndarray
        With ``variance`` only: the whitened residual per order.
    directions : int or None
        With ``variance`` only: :func:`noise_directions` of the last stage's projection.
    """
    N, ny, nu = H.shape
    while n_max > 4 and subspace.scan_block_rows(n_max, ny) * (nu + ny) > 2 * N * nu:
        n_max -= 2  # the scan's larger block rows must fit the (full) data too
    stage = min(n_max, first_stage(n_peaks))
    while True:
        planned = scan_orders(max(4, stage))
        key = (stage, variance is not None)
        if stages is None or key not in stages:
            basis = subspace.row_basis(z, subspace.scan_block_rows(int(planned[-1]), ny))
            staged: list[tuple[int, np.ndarray, np.ndarray]] = []
            kwargs: dict = {} if variance is None else {
                "variance": variance, "params": params, "z_alarm": z_alarm}
            S = None
            if variance is not None:  # kept for the noise's directions, should the scan end here
                S = subspace.single_schur(basis, H, weights, jobs)
                kwargs["schur"] = S
            result = misfit_scan(z, H, planned, basis, weights=weights,
                                 stop_after=2 * n_peaks + 40, models=staged, jobs=jobs,
                                 **kwargs)
            if stages is not None:
                stages[key] = (result, staged, basis, S)
        else:
            result, staged, basis, S = stages[key]
        if models is not None:
            models[:] = staged  # only the last stage's models are kept
        if variance is None:
            orders, misfit = result
            if (orders.size < planned.size or stage >= n_max
                    or not still_falling(orders, misfit)
                    or _splits(order_at_floor(orders, misfit), split_above)):
                return orders, misfit
        else:
            orders, misfit, chi2 = result
            n0 = significant_order(orders, chi2, params, z_alarm, ORDER_TOLERANCE)
            # a misfit still falling extends the stage only while the model of n0 is not
            # yet within the noise: beyond that it is noise being fitted (a 6-DOF chain
            # whose upper band is noise: n0 = 12 at a residual 0.97 times its degrees of
            # freedom, and the scan went on to 208 states)
            if (orders.size < planned.size or stage >= n_max
                    or _splits(n0, split_above)
                    or (n0 <= orders[-1] - (orders[-1] - orders[0]) / 3.0
                        and (not still_falling(orders, misfit)
                             or fits_noise(chi2[list(orders).index(n0)],
                                           min(N, SCAN_LINES), ny, nu, n0)))):
                return orders, misfit, chi2, noise_directions_of(S, basis, variance, weights)
        stage = min(n_max, 2 * stage)


NOISE_EIGENVALUE_MARGIN = 2.0
"""A direction of the noise-whitened projection counts as the system's when its eigenvalue
exceeds this many times the largest that noise alone gives (:func:`noise_directions`).
The noise variance estimated from the data is within about 20 % of the truth
(``tests/test_noise.py``); pure noise of any variance shape stays below this margin
(``tests/test_noise_directions.py``), and on the calibration seeds 281 and 283 (64 files,
86 scans) the largest eigenvalue below it was at most 2.0 times the edge, while the count
never fell below twice the band's clear and marginal modes. A mode adds about half its
squared signal-to-noise ratio to each of its two directions, so the margin still counts a
mode of SNR 3."""


def noise_directions(eigenvalues: np.ndarray, n_rows: int, n_columns: int) -> int | None:
    """The directions of a noise-whitened projection above the noise: how many states the
    data show.

    Noise alone, whitened by its own covariance, gives a Wishart matrix of ``n_rows`` rows
    over ``n_columns`` columns scaled by ``1 / n_columns``; its largest eigenvalue lies
    near the Marchenko-Pastur edge ``(1 + sqrt(n_rows / n_columns))^2``. The count of
    eigenvalues above :data:`NOISE_EIGENVALUE_MARGIN` times that edge, rounded up to even
    (a mode is two states).

    Returns
    -------
    int or None
        None when the count does not stop short of ``n_rows`` (all the rows but two
        above the noise: the projection saw no noise floor, so it bounds nothing).
    """
    ev = np.asarray(eigenvalues, dtype=float)
    if ev.size == 0 or n_columns <= 0 or not np.all(np.isfinite(ev)):
        return None
    edge = (1.0 + np.sqrt(n_rows / n_columns)) ** 2
    count = int(np.count_nonzero(ev > NOISE_EIGENVALUE_MARGIN * edge))
    count += count % 2
    return None if count >= n_rows - 2 else count


def noise_directions_of(
    S: np.ndarray, basis: subspace.RowBasis, variance: np.ndarray,
    weights: np.ndarray | None,
) -> int | None:
    """:func:`noise_directions` of the projection ``S``
    (:func:`automodal.core.subspace.single_schur` of data with ``basis`` and ``weights``),
    whitened by the noise ``variance``
    (:func:`automodal.core.subspace.noise_whitened_spectrum`); None if the noise covariance
    is singular."""
    try:
        ev, columns = subspace.noise_whitened_spectrum(S, basis, variance, weights)
    except np.linalg.LinAlgError:
        return None
    return noise_directions(ev, S.shape[0], columns)


DIRECTIONS_EXCESS = 2.0
"""``n0`` under the significance rule takes at most this many times the states the
projection shows above the noise (:func:`capped_order`). Capped at the states alone,
high-SNR files lost clear modes that the extra states had let the subspace models fit
(calibration seed 281: f_18, a 6 x 1 chain with 1 % proportional noise, lost 34.46 Hz at an
SNR of 1795 with 20 states against 34; f_17, a 34 x 3 dense grid, one mode and five
intervals): those states absorb the subspace estimate's own bias. The significance test
gave ``n0`` up to about twice the true order where the models reach the noise (the
calibration of :data:`SIGNIFICANT_EXCESS`), so the cap leaves those alone."""


def capped_order(orders: np.ndarray, n: int, directions: int | None) -> int:
    """``n``, at most the smallest scanned order that holds :data:`DIRECTIONS_EXCESS` times
    ``directions`` states.

    The significant order of the whitened residual (:func:`significant_order`) reads every
    gain of a higher order as modes; where the subspace models stay off the data by more
    than the noise (a high-SNR chain with proportional noise: the residual of the true
    order's model 25 to 500 times its degrees of freedom, from the subspace estimate's own
    bias), those gains are that bias shrinking, and the order ran to 3-6 times the true one
    (family seed 281, f_15: 58 states for 6 modes; 283 f_13: 76 for 10). The directions the
    projection shows above the noise do not depend on any model's fit."""
    if directions is None:
        return int(n)
    orders = np.asarray(orders)
    holding = orders[orders >= DIRECTIONS_EXCESS * directions]
    return int(min(n, holding[0] if holding.size else orders[-1]))


@dataclass
class OrderChoice:
    """The orders :func:`select_orders` chose.

    Attributes
    ----------
    scanned : ndarray of int
        Orders of the misfit scan.
    misfit : ndarray
        ``MC`` at each scanned order.
    n0 : int
        Order at which the misfit reached its floor, or (with a noise model) the
        significant order of the whitened residual.
    reference : int
        The excessive order of the reference model and the replicates.
    limit : int
        Largest order the data (and ``max_order``) allowed.
    chi2 : ndarray or None
        The whitened residual per scanned order (with a noise model).
    rule : str
        ``"floor"`` or ``"significance"``: how ``n0`` was chosen.
    models : list of (n, mu, C V)
        The discrete-time state and output matrices of every scanned order (of the scan
        that chose ``n0``), for the stabilization diagram.
    block_rows : int
        Block rows of the reference model
        (:func:`automodal.core.subspace.reference_block_rows` of the outputs' rank above
        the noise, when known; at least ``min_block_rows`` of :func:`select_orders` as far
        as the lines allow).
    complete : bool
        Whether the scan ended where it would have without ``split_work``: its last
        stage's order was below the one that ends a scan early (``split_above`` of
        :func:`scan`), so a scan without ``split_work`` would give the same choice.
    noise_directions : int or None
        With a noise model: the states the scan's projection shows above the noise
        (:func:`noise_directions`), the most ``n0`` takes under the significance rule;
        None without a noise model, or where the projection saw no noise floor.
    """

    scanned: np.ndarray
    misfit: np.ndarray
    n0: int
    reference: int
    limit: int
    chi2: np.ndarray | None = None
    rule: str = "floor"
    models: list[tuple[int, np.ndarray, np.ndarray]] = field(default_factory=list)
    block_rows: int = 0
    complete: bool = True
    noise_directions: int | None = None


SIGNIFICANT_EXCESS = 2.0
"""Reference order over ``n0`` when ``n0`` comes from the significance test: on the 48
calibration files (seeds 211, 214, 215, 218) that ``n0`` was never below 0.9 times the
true order (median 1.35 times), where the misfit floor gave about half of it."""

ORDER_TOLERANCE = 0.1
"""``tolerance`` of :func:`significant_order` in the pipeline (calibration files: 0.05
and 0.1 gave the same smallest n0 / true order ratio, 1.0 at the 10th percentile, 0.1 a
smaller median excess 1.35 against 1.39; 0.2 fell below 0.9 on two files)."""

ORDER_Z = 3.0
"""False-alarm quantile of the order test (:func:`significant_order`): one-sided normal
tail 0.13 % per comparison."""


def select_orders(
    z: np.ndarray,
    H: np.ndarray,
    weights: np.ndarray,
    max_order: int | None = None,
    source: str | None = None,
    variance: np.ndarray | None = None,
    z_alarm: float = ORDER_Z,
    rank: int | None = None,
    split_work: float | None = None,
    reference_cap: int | None = None,
    stages: dict | None = None,
    jobs: int | None = None,
    min_block_rows: int | None = None,
) -> OrderChoice:
    """Scan the misfit and choose ``n0`` and the reference order.

    Parameters
    ----------
    z : ndarray, shape (N,)
        Lines on the unit circle.
    H : ndarray, shape (N, ny, nu)
        FRF, channel-scaled.
    weights : ndarray, shape (N,)
        Line weights of the fits.
    max_order : int, optional
        Largest order considered (rounded down to even); it also lifts the automatic cap
        :data:`MAX_REFERENCE_ORDER` of the reference order.
    source : str, optional
        The data's file, named in errors.
    variance : ndarray, shape (N, ny, nu), optional
        Noise variance of ``H``'s entries (in ``H``'s units): ``n0`` is then the
        significant order of the whitened residual (:func:`significant_order`) instead of
        the floor of the log misfit (:func:`order_at_floor`).
    z_alarm : float
        False-alarm quantile of the order test.
    rank : int, optional
        Independent directions of the outputs above the noise
        (:func:`automodal.core.whitening.output_rank`): fewer than ``ny`` raise the
        reference model's block rows (:func:`automodal.core.subspace.reference_block_rows`).
    split_work : float, optional
        The work of one replicate (:func:`automodal.core.sub_bands.replicate_work`) above
        which the caller splits the band: the scan ends at the stage whose ``n0`` implies a
        reference that costly (``split_above`` of :func:`scan`).
    reference_cap : int, optional
        Largest reference order (and ``n0``): a sub-band's, that of the band it was cut
        from. A sub-band holds a share of its band's modes, so its model needs no more
        states than the band's; where the models are not near the data the misfit floor
        of a sub-band can lie higher (ModeLAB's beam, a 7888-line sub-band: 54 states
        against the band's 36, with a 1-output roving-hammer test's block rows, over
        10 minutes and 3 GB instead of 17 s).
    stages : dict, optional
        The scan's stages, kept and reused (``stages`` of :func:`scan`): a dict shared by
        the calls on the same data.
    jobs : int or None
        Worker threads of the scan (:func:`misfit_scan`).
    min_block_rows : int, optional
        At least this many block rows for the reference model (``Settings.block_rows``), at
        most what a replicate's lines allow (:func:`block_row_budget`).

    Raises
    ------
    InputError
        When the band has too few lines for ``max_order``, or for order 4.
    """
    N, ny, nu = H.shape
    n_limit = order_limit(N, ny, nu)
    if max_order is not None:
        need = lines_needed(int(max_order), ny, nu)
        if N < need:
            raise InputError(
                f"{N} frequency lines in the band are too few for model order {max_order}:"
                f" the identification needs at least {need}",
                source,
            )
        n_limit = min(n_limit, int(max_order) - int(max_order) % 2)
    if n_limit < 4:
        raise InputError(
            f"{N} frequency lines in the band are too few: the identification needs at least"
            f" {lines_needed(4, ny, nu)}",
            source,
        )
    n_scan = min(n_limit, MAX_SCAN_ORDER)
    cap = n_limit if max_order is not None else min(n_limit, MAX_REFERENCE_ORDER)
    if reference_cap is not None:
        cap = max(4, min(cap, int(reference_cap) - int(reference_cap) % 2))
    chi2 = directions = None
    rule = "floor" if variance is None else "significance"
    models: list[tuple[int, np.ndarray, np.ndarray]] = []
    if variance is None:
        split_above = _split_above(N, ny, nu, cap, 3.0, split_work)
        orders, misfit = scan(z, H, weights, n_scan, count_peaks(H), models=models,
                              split_above=split_above, stages=stages, jobs=jobs)
        n0 = order_at_floor(orders, misfit)
        if rank is not None and rank < ny:
            # the envelope path after a noise model the scan could not fit: the outputs'
            # few directions above that noise raise the block rows (below) as 1.2 n / rank,
            # so the floor's order is kept to what those directions can hold, as
            # order_off_the_noise keeps the significance test's
            n0 = min(n0, max(2, STATES_PER_DIRECTION * int(rank)))
    else:
        p = mode_parameters(ny, nu)
        tv = test_variance(H, variance)
        split_above = _split_above(N, ny, nu, cap, SIGNIFICANT_EXCESS, split_work)
        orders, misfit, chi2, directions = scan(
            z, H, weights, n_scan, count_peaks(H, variance=tv), tv, p, z_alarm, models=models,
            split_above=split_above, stages=stages, jobs=jobs)
        n0 = significant_order(orders, chi2, p, z_alarm, ORDER_TOLERANCE)
    complete = not _splits(n0, split_above)  # the scan's own n0, as its last stage saw it
    if variance is not None:
        i0 = int(np.flatnonzero(orders == n0)[0])
        if not fits_noise(chi2[i0], min(N, SCAN_LINES), ny, nu, n0):
            n0, rule = order_off_the_noise(n0, order_at_floor(orders, misfit), ny, rank)
        if rule == "significance":
            # the model test above judges the significant order itself; the directions
            # the noise leaves cap what that test keeps (never raise it)
            n0 = capped_order(orders, n0, directions)
    n_ref = excessive_order(n0, cap, reference_factor(rule))
    n0 = min(n0, n_ref)
    q = subspace.block_rows(n_ref, ny)
    # a replicate's lines bound the block rows asked for beyond the default
    rows = block_row_budget(N, ny, nu)
    if rank is not None and rank < ny:
        # outputs with fewer independent directions than sensors need more block rows
        q = max(q, min(subspace.reference_block_rows(n_ref, ny, rank), rows))
    if min_block_rows is not None:
        q = max(q, min(int(min_block_rows), rows))
    return OrderChoice(scanned=orders, misfit=misfit, n0=n0, reference=n_ref, limit=n_limit,
                       chi2=chi2, rule=rule, models=models, block_rows=q, complete=complete,
                       noise_directions=directions)


def reference_factor(rule: str) -> float:
    """The reference order over ``n0`` (``factor`` of :func:`excessive_order`) after each
    rule: 3 after the misfit floor, which stops short of the true order;
    :data:`SIGNIFICANT_EXCESS` after the significance test, which does not."""
    return 3.0 if rule == "floor" else SIGNIFICANT_EXCESS


def order_off_the_noise(n0: int, floor: int, ny: int, rank: int | None) -> tuple[int, str]:
    """``n0`` and its rule when the significant order's model does not fit the noise.

    No scanned model is significantly better than ``n0``'s, and ``n0``'s does not fit the
    data in the noise's terms either (:func:`fits_noise`): the models are not near the
    data, and the test has nothing to say where the log misfit still falls. An 80-mode grid
    seen by 40 sensors on half of it: the whitened residual rose from 8e8 at order 2, 1700
    times its degrees of freedom, to 1e11-2e12 up to order 240, while the log misfit fell
    from 9.3 to 1.3. A 39-output dense grid's sub-band of 15 modes (family seed 281, f_11):
    320 times at order 4, 400 to 30 000 times above it, the log misfit from 1.35 to 0.16
    by order 36. So the misfit ``floor`` (:func:`order_at_floor`) decides when it lies
    above ``n0`` (rule ``"floor"``).

    Nor does the test's order stand on anything where it lies above the floor: its
    "significant" gains are then the misfit's slow fall, not modes. Where the outputs show
    ``rank`` directions above the noise, fewer than their ``ny`` sensors
    (:func:`automodal.core.whitening.output_rank`), about one per mode the band holds,
    ``n0`` is kept to :data:`STATES_PER_DIRECTION` states per direction, and not below
    the floor. A 20-output grid's 0-21 Hz sub-band with 5 modes, 2 % proportional noise on
    an accelerance the models miss near 0 Hz, chi2 250 times its degrees of freedom (family
    seed 252, f_22): ``n0 = 92`` against a floor of 12 and 7 directions, 87 s for the file;
    now 28 states.

    Returns
    -------
    (int, str)
        The order and its rule (``"floor"`` or ``"significance"``).
    """
    if floor > n0:
        return int(floor), "floor"
    if rank is not None and rank < ny:
        return int(min(n0, max(floor, STATES_PER_DIRECTION * int(rank)))), "significance"
    return int(n0), "significance"


def _splits(n0: int, split_above: int | None) -> bool:
    """Whether a scan stage whose order is ``n0`` ends the scan because the caller will
    split the band (``split_above`` of :func:`scan`)."""
    return split_above is not None and n0 >= split_above


def _split_above(
    N: int, ny: int, nu: int, cap: int, factor: float, work: float | None
) -> int | None:
    """The smallest ``n0`` whose reference (``factor`` times it, at most ``cap``) would cost
    more than ``work`` per replicate (:func:`automodal.core.subspace.replicate_work`), or
    None."""
    if work is None:
        return None
    for n0 in range(2, cap + 1, 2):
        if subspace.replicate_work(N, ny, nu, excessive_order(n0, cap, factor)) > work:
            return n0
    return None


STATES_PER_DIRECTION = 4
"""At most this many states per direction of the outputs above the noise
(:func:`automodal.core.whitening.output_rank`) when the significance test's order does not
fit the noise: two per mode, and twice the modes the directions show (weak modes add
directions below the rank's threshold)."""

NOISE_CONSISTENT = 2.0
"""The smallest model fits the data when its whitened residual is at most this many times
its degrees of freedom: pure noise gives about 1, within the accuracy of a noise variance
estimated from the data (20 %, ``tests/test_noise.py``); structure the model cannot
explain gives orders of magnitude more."""


def fits_noise(chi2: float, n_lines: int, ny: int, nu: int, n: int) -> bool:
    """Whether a model of ``n`` states leaves a whitened residual ``chi2`` (on ``n_lines``
    lines) consistent with the noise: at most :data:`NOISE_CONSISTENT` times its degrees
    of freedom."""
    dof = 2.0 * n_lines * ny * nu - (int(n) // 2) * mode_parameters(ny, nu)
    return bool(np.isfinite(chi2) and chi2 <= NOISE_CONSISTENT * max(dof, 1.0))
