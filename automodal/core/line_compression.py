"""Fewer frequency lines for bands sampled far more finely than their responses last.

Lines spaced ``df`` apart describe a response of up to ``1 / df`` seconds: the inverse DFT
of a band's ``N`` lines is its (band-limited) impulse response, ``N`` samples over that
time. A band whose response falls into the noise long before ``1 / df`` (a long record
analysed in one block, or an FFT zero-padded for a fine display) carries the same
information in fewer lines: the response is cut to a window that holds it and the FRF of
the cut response is taken at every ``K``-th line. This is not keeping every ``K``-th line.
Keeping lines is exact at the lines kept and throws the others' noise averaging away (the
poles' variance grows ``K`` times); the cut keeps it: a compressed line is a weighted sum
of about ``K`` neighbouring lines, with about ``1 / K`` of their noise variance
(:func:`compressed_variance` propagates it exactly), and its error is the part of the
response outside the window.

Whether a cut is safe is judged on the data, not on the peaks seen (a narrow or weak mode
that no peak search counts still rings in the impulse response, and still leaves a
residual where the cut loses it):

1. **Where the response ends** (:func:`response_tails`). The band's FRF, less a smooth
   cubic that joins its two ends (the DFT treats the band as periodic, and a jump between
   its ends would ring as ``1 / t``), is transformed to time; each entry's energy is
   averaged over blocks and compared with its noise level (the noise model's variance over
   the lines, or less where the record's quiet middle is quieter: the lower is the
   cautious one). The response is seen as far as a block stands out of the noise at a
   familywise false-alarm probability of :data:`FALSE_ALARM`, and its decay there is
   fitted. A block's noise energy follows the noise model: white in time where the
   variance is flat over the lines, correlated over about a resonance's decay where it
   follows the response (proportional or H1 noise), and then far more scattered
   (:func:`block_energy_shape`); taken as white, such noise is seen as response over the
   whole record and no band is compressed.
2. **The cut** keeps at least twice that on either side of time zero, and as much more as
   the fitted decay needs for the response cut off to make an error below
   :data:`TAIL_ERROR` of a compressed line's noise variance (:meth:`Tail.cut_allowed`: a
   response still stands below the noise after it is last seen, and its sum over the lines
   is coherent). At least the lines the identification's orders need are kept (the
   caller's ``min_lines``: :func:`automodal.core.order.lines_for_orders`), and only bands
   of more than twice as many are compressed; and every resonance seen keeps
   :data:`KEPT_LINES_PER_BAND` kept lines across its half-power band (its width from the
   decay fitted where it is last seen).
3. **The check** (:func:`residual_excess`): the lines the window's FRF leaves unexplained
   (the response outside the window, plus noise) must be noise: their squared residual over
   its noise variance (:func:`_residual_variance`, exact for noise that varies over the
   lines), summed over 1, 2, 4, ... up to ``K`` neighbouring lines of every
   entry, must stay below the Gamma quantile of :data:`FALSE_ALARM` over all these tests. A
   feature the blocks missed (a weak mode whose ringing lasts the record: under the noise at
   every instant, a peak of a few lines in frequency) fails it, and ``K`` is halved until it
   passes, or no compression is made.

The lines kept are lines of the band (every ``K``-th, from its first), so that the line
spacing the identification sees is a real one: the window holds every response the check
can see, so a mode it holds spans as many of the kept lines as its ringing allows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FALSE_ALARM = 1e-3
"""Familywise probability that pure noise makes `response_tails` see response in a
block, or :func:`residual_excess` reject a cut (each over all its tests)."""

UNIFORM_TOLERANCE = 1e-6
"""Lines are evenly spaced when every spacing is within this share of their mean (the
DFT's requirement)."""

EDGE_LINES = 32
"""Lines at each end of the band whose straight-line fit gives the end's value and slope
for the cubic that joins the ends (:func:`_edge_cubic`)."""

MAX_BLOCKS = 1024
"""Blocks of the impulse response over which :func:`response_tails` averages the energy
(at most; each at least :data:`MIN_BLOCK` samples)."""

MIN_BLOCK = 16
"""Fewest samples averaged in a block: the noise energy of a block is then within a factor
of about 2 of its mean at the familywise level."""

TAIL_ERROR = 0.1
"""Largest error the cut may make at a compressed line, from the response's decay
extrapolated past the cut, as a share of that line's noise variance (a third of its noise
deviation): within what the noise model itself is uncertain by."""

KEPT_LINES_PER_BAND = 6.0
"""Fewest kept lines across the half-power band of every resonance the tail rule sees (its
width from the decay fitted there: ``N rate / (2 pi)`` lines). Fewer lines per resonance keep
its information but not the estimators' precision: the noisy SISO accelerance of
``automodal simulate`` (6000 lines, 10 % additive noise, its lowest mode 17.7 lines wide)
kept compressed by 10, 5, 4, 3 and 2 left that mode 1.7, 3.5, 4.3, 5.8 and 8.7 lines wide and
its frequency interval 12, 3.0, 1.9, 1.1 and 0.9 times as wide as the whole band's (damping
4.2, 2.9, 1.5, 1.3, 1.3)."""


@dataclass(frozen=True)
class CompressionPlan:
    """How a band is compressed: every ``factor``-th of its ``n_lines`` lines is kept, as
    the FRF of its impulse response cut to the first ``positive`` and the last
    ``negative`` samples (``positive + negative = n_lines // factor``)."""

    n_lines: int
    factor: int
    positive: int
    negative: int

    def __post_init__(self) -> None:
        if not (self.factor >= 2 and self.positive >= 1 and self.negative >= 1
                and self.positive + self.negative <= self.n_lines // self.factor):
            raise ValueError(f"inconsistent compression plan {self!r}")

    @property
    def kept(self) -> np.ndarray:
        """Indices of the lines kept."""
        return np.arange(0, self.n_lines, self.factor)

    def window(self) -> np.ndarray:
        """The cut, ``(n_lines,)``: 1 on the samples kept, 0 elsewhere."""
        w = np.zeros(self.n_lines)
        w[: self.positive] = 1.0
        w[self.n_lines - self.negative:] = 1.0
        return w


def is_uniform(frequency: np.ndarray) -> bool:
    """Whether ``frequency`` (increasing) is evenly spaced within
    :data:`UNIFORM_TOLERANCE`."""
    f = np.asarray(frequency, dtype=float)
    if f.size < 3:
        return False
    d = np.diff(f)
    mean = (f[-1] - f[0]) / (f.size - 1)
    return bool(mean > 0 and np.max(np.abs(d - mean)) <= UNIFORM_TOLERANCE * mean)


def _entries(a: np.ndarray) -> np.ndarray:
    """``(N, ...)`` as ``(N, C)``."""
    return a.reshape(a.shape[0], -1)


def _edge_ends(H: np.ndarray) -> np.ndarray:
    """Each entry's value and slope (per line) at the band's first line and one line past
    its last, from straight-line fits over :data:`EDGE_LINES` lines at each end,
    ``(4, C)``: the ends the cubic of :func:`_edge_cubic` joins."""
    N = H.shape[0]
    m = min(EDGE_LINES, N // 4)
    k = np.arange(m, dtype=float)
    pinv = np.linalg.pinv(np.column_stack([np.ones(m), k - (m - 1) / 2.0]))
    lo = pinv @ H[:m]  # value at the middle of the first m lines, slope per line
    hi = pinv @ H[N - m:]
    c = (m - 1) / 2.0
    return np.stack([lo[0] - c * lo[1], lo[1], hi[0] + (c + 1.0) * hi[1], hi[1]])


def _edge_cubic(ends: np.ndarray, n_lines: int, lines: np.ndarray) -> np.ndarray:
    """The cubic (in the line index) through :func:`_edge_ends`'s values and slopes, at
    ``lines``, ``(lines, C)``: the FRF less it is continuous, with its slope, where the
    DFT joins the band's ends."""
    v0, s0, v1, s1 = ends
    x = (np.asarray(lines, dtype=float) / n_lines)[:, None]
    h00, h10 = 2 * x**3 - 3 * x**2 + 1, x**3 - 2 * x**2 + x
    h01, h11 = -2 * x**3 + 3 * x**2, x**3 - x**2
    return h00 * v0 + h10 * (s0 * n_lines) + h01 * v1 + h11 * (s1 * n_lines)


@dataclass(frozen=True)
class _Response:
    """A band's impulse response: the inverse DFT of its FRFs less their edge cubic,
    ``h`` ``(N, C)``, and the cubic's ends (:func:`_edge_ends`). Computed once, it serves
    the extent, every factor's check and the compression."""

    h: np.ndarray
    ends: np.ndarray

    @classmethod
    def of(cls, H: np.ndarray) -> _Response:
        Hc = _entries(np.asarray(H))
        N = Hc.shape[0]
        ends = _edge_ends(Hc)
        return cls(h=np.fft.ifft(Hc - _edge_cubic(ends, N, np.arange(N)), axis=0), ends=ends)


def _gamma_quantile(shape: np.ndarray | float, tail: float) -> np.ndarray:
    """The value a Gamma(``shape``, 1) variable exceeds with probability ``tail``."""
    from scipy.special import gammainccinv

    return np.asarray(gammainccinv(shape, tail), dtype=float)


@dataclass(frozen=True)
class Tail:
    """Where one entry's impulse response, on one side of time zero, is last seen above the
    noise, and how it decays there (:func:`response_tails`).

    Attributes
    ----------
    side : int
        0 after time zero, 1 before it (the last samples of the DFT).
    end : int
        Samples from time zero to the end of the last block standing out of the noise.
    excess : float
        The response's energy per sample there, in the entry's noise per sample (the
        fitted decay's value).
    rate : float
        Its energy's decay rate per sample (``inf`` where it fell within one block; 0 where
        no decay could be fitted: the response may last the record).
    """

    side: int
    end: int
    excess: float
    rate: float

    def cut_allowed(self, kept: int, window: int) -> bool:
        """Whether cutting this side after ``kept`` samples, in a window of ``window``,
        leaves at most :data:`TAIL_ERROR` of a compressed line's noise variance as error.

        The decay extrapolated past the cut (energy ``excess exp(-rate (t - end))``) sums
        to ``S = e / rate`` (``e`` its value at the cut); its error on a line is at most
        ``(sum |h|)^2 = 4 S / rate`` against the ``window`` samples of noise of a
        compressed line."""
        if kept < 2 * self.end:
            return False
        if np.isinf(self.rate):
            return True
        if not self.rate > 0:
            return False
        at_cut = self.excess * np.exp(-self.rate * (kept - self.end))
        return bool(4.0 * at_cut / self.rate**2 <= TAIL_ERROR * window)


def response_tails(H: np.ndarray, variance: np.ndarray) -> list[Tail]:
    """Where the band's impulse response stands out of the noise, per entry and side of
    time zero, and how fast it decays there (step 1 of the module's rule).

    Parameters
    ----------
    H : ndarray, shape (N, ...)
        The band's FRFs, on evenly spaced lines.
    variance : ndarray, shape of ``H``
        Their noise variance.

    Returns
    -------
    list of Tail
        One per entry and side where a block stands out.
    """
    return _tails(_Response.of(H), _entries(np.asarray(variance, dtype=float)))


def _tails(response: _Response, variance: np.ndarray) -> list[Tail]:
    """:func:`response_tails` of a band's response (``variance`` ``(N, C)``)."""
    N, C = response.h.shape
    half = N // 2
    n_blocks = max(1, min(MAX_BLOCKS // 2, half // MIN_BLOCK))
    L = max(1, half // n_blocks)
    shape = block_energy_shape(variance, L)
    # a block's energy over the noise's, when it holds noise only: Gamma(shape, 1 / shape)
    limit = _gamma_quantile(shape, FALSE_ALARM / (2 * n_blocks * C)) / shape
    centre = (np.arange(n_blocks) + 0.5) * L
    e = np.abs(response.h) ** 2
    level = np.mean(variance, axis=0) / N  # a line's noise spread over the samples
    sides = (e[: n_blocks * L].reshape(n_blocks, L, -1).mean(axis=1),
             e[::-1][: n_blocks * L].reshape(n_blocks, L, -1).mean(axis=1))
    # the record's quiet middle (the last quarter of each side's blocks), where it is below
    # the noise model's level: the lower level is the cautious one. The blocks' median is
    # the Gamma law's (mean 1), below its mean where the noise is correlated across a block
    quiet = np.median(np.concatenate([b[-max(1, n_blocks // 4):] for b in sides]), axis=0)
    level = np.minimum(level, quiet * shape / _gamma_quantile(shape, 0.5))
    level = np.where(level > 0, level, np.inf)
    tails: list[Tail] = []
    for side, blocks in enumerate(sides):
        x = blocks / level[None, :]
        for c in np.flatnonzero(np.any(x > limit, axis=0)):
            last = int(np.flatnonzero(x[:, c] > limit[c])[-1])
            tails.append(_tail(side, x[: last + 1, c] - 1.0, centre[: last + 1], L))
    return tails


POWER_ITERATIONS = 30
"""Power iterations of :func:`block_energy_shape` (from a fixed start: the same numbers on
every run). Its Rayleigh quotient never exceeds the largest eigenvalue, so an iteration
short of convergence gives a larger shape, a lower limit and a longer response: the
cautious side."""


def block_energy_shape(variance: np.ndarray, L: int) -> np.ndarray:
    """The Gamma shape of a block's noise energy in the impulse response, per entry.

    Noise independent from line to line, of variance ``v_k`` at line ``k`` of ``N``, is
    stationary in the inverse DFT, with covariance ``r(d) = ifft(v)[d] / N`` between
    samples ``d`` apart: white where ``v`` is flat, correlated over about a resonance's
    decay where the noise follows the response (proportional or H1 noise). The energy of
    ``L`` consecutive samples is then ``sum lambda_i X_i``, ``X_i`` standard exponential
    and ``lambda_i`` the eigenvalues of their Toeplitz covariance; a Gamma law of the same
    mean whose tail decays as the largest term's, shape ``L r(0) / lambda_max``, is the
    cautious one (``L`` for white noise, down to 1 where the block's samples move as one).

    Parameters
    ----------
    variance : ndarray, shape (N, C)
        Each entry's noise variance at the lines.
    L : int
        Samples in a block.

    Returns
    -------
    ndarray, shape (C,)
        The shape, in ``[1, L]``.
    """
    v = np.asarray(variance, dtype=float)
    N, C = v.shape
    r = np.fft.ifft(v, axis=0)[:L] / N  # r(d), d = 0 .. L - 1; r(-d) = conj r(d)
    r0 = r[0].real
    if L == 1:
        return np.ones(C)
    # the covariance's product with a block vector: its circulant embedding over 2 L
    c = np.concatenate([r, np.zeros((1, C)), np.conj(r[:0:-1])])
    spectrum = np.fft.fft(c, axis=0)
    u = np.exp(2j * np.pi * np.random.default_rng(0).random((L, 1))) * np.ones((1, C))
    for _ in range(POWER_ITERATIONS):
        u = u / np.linalg.norm(u, axis=0)
        Ru = np.fft.ifft(spectrum * np.fft.fft(u, n=2 * L, axis=0), axis=0)[:L]
        top = np.sum(np.conj(u) * Ru, axis=0).real
        u = Ru
    positive = r0 > 0
    shape = np.full(C, float(L))
    shape[positive] = L * r0[positive] / top[positive]
    return np.clip(shape, 1.0, float(L))


def _tail(side: int, excess: np.ndarray, centre: np.ndarray, L: int) -> Tail:
    """A :class:`Tail` from the blocks' energy excess over the noise up to the last block
    standing out: the decay fitted (least squares of its logarithm) over the later half of
    them."""
    last = excess.size - 1
    end = (last + 1) * L
    if last == 0:
        return Tail(side=side, end=end, excess=float(excess[0]), rate=np.inf)
    sel = np.arange(last // 2, last + 1)
    sel = sel[excess[sel] > 0]
    if sel.size < 2:
        return Tail(side=side, end=end, excess=float(excess[last]), rate=0.0)
    slope, intercept = np.polyfit(centre[sel], np.log(excess[sel]), 1)
    return Tail(side=side, end=end, excess=float(np.exp(intercept + slope * end)),
                rate=float(max(-slope, 0.0)))


def residual_excess(H: np.ndarray, variance: np.ndarray, plan: CompressionPlan) -> bool:
    """Whether the lines the cut leaves unexplained hold more than noise (step 3 of the
    module's rule): ``True`` rejects the plan.

    The residual ``H - (the window's FRF)`` (the DFT of the response outside the window) at
    every line has the noise variance of :func:`_residual_variance` (about the line's
    variance times ``1 - W / N``, ``W`` the samples kept, where it is flat over the cut's
    kernel). Its squared magnitude over that, summed over ``s = 1, 2, 4, ...`` (up to the factor)
    neighbouring lines of every entry, is compared with the Gamma(``s``) quantile of
    :data:`FALSE_ALARM` shared by all the sums.
    """
    return _excess(_Response.of(H), _entries(np.asarray(variance, dtype=float)), plan)


def _excess(response: _Response, variance: np.ndarray, plan: CompressionPlan) -> bool:
    """:func:`residual_excess` of a band's response (``variance`` ``(N, C)``)."""
    N, C = response.h.shape
    scales = [1 << i for i in range(int(np.log2(plan.factor)) + 1)]
    limits = _gamma_quantile(np.asarray(scales, dtype=float),
                             FALSE_ALARM / (len(scales) * N * C))
    outside = np.fft.fft(response.h * (1.0 - plan.window())[:, None], axis=0)
    x = np.abs(outside) ** 2 / _residual_variance(variance, plan)
    c = np.concatenate([np.zeros((1, C)), np.cumsum(x, axis=0)])
    return any(s <= N and np.max(c[s:] - c[:-s]) > limit for s, limit in zip(scales, limits))


def _window_convolved(variance: np.ndarray, plan: CompressionPlan) -> np.ndarray:
    """``sum_j |c_{k-j}|^2 v_j`` at every line ``k`` (``variance`` ``(N, C)``), ``c`` the
    cut's kernel (the DFT of the window over ``N``, ``c_0 = W / N``): the noise variance of
    the window's FRF at each line."""
    kernel = np.abs(np.fft.fft(plan.window()) / plan.n_lines) ** 2
    return np.fft.ifft(np.fft.fft(variance, axis=0) * np.fft.fft(kernel)[:, None], axis=0).real


def _residual_variance(variance: np.ndarray, plan: CompressionPlan) -> np.ndarray:
    """The noise variance of the residual the cut leaves at every line (``variance``
    ``(N, C)``): the line's noise less the window's FRF of it, ``v_k (1 - 2 W / N) +
    sum_j |c_{k-j}|^2 v_j`` (:func:`_window_convolved`). Where ``v`` is flat over the
    kernel this is ``v_k (1 - W / N)``; where the noise follows a resonance (proportional
    or H1 noise) it is not, and the flat form reads the difference as response."""
    kept = (plan.positive + plan.negative) / plan.n_lines
    out = variance * (1.0 - 2.0 * kept) + _window_convolved(variance, plan)
    # the residual's coefficients have squared norm 1 - W / N: never below that of the
    # smallest variance (rounding of the convolution)
    return np.maximum(out, np.min(variance, axis=0)[None, :] * (1.0 - kept))


def plan_compression(frequency: np.ndarray, H: np.ndarray, variance: np.ndarray,
                     min_lines: int) -> CompressionPlan | None:
    """The compression of a band by the module's rule, or ``None`` (lines not evenly
    spaced, at most ``2 min_lines`` of them, a response that lasts too long, or no factor
    whose cut passes :func:`residual_excess`).

    Parameters
    ----------
    frequency : ndarray, shape (N,)
        The band's lines (Hz).
    H : ndarray, shape (N, ny, nu)
        Its FRFs.
    variance : ndarray, shape (N, ny, nu)
        Their noise variance (> 0).
    min_lines : int
        Fewest lines kept (:func:`automodal.core.order.lines_for_orders`).
    """
    N = int(np.shape(H)[0])
    if N <= 2 * min_lines or not is_uniform(frequency):
        return None
    response = _Response.of(H)
    v = _entries(np.asarray(variance, dtype=float))
    tails = _tails(response, v)
    positive = max((t.end for t in tails if t.side == 0), default=0)
    negative = max((t.end for t in tails if t.side == 1), default=0)
    factor = min(N // max(2 * (positive + negative), min_lines), _resolution_cap(tails, N))
    while factor >= 2:
        W = N // factor
        # the samples kept are shared in proportion to the two extents
        pos = min(W - 1, max(1, int(round(W * (positive + 1) / (positive + negative + 2)))))
        plan = CompressionPlan(n_lines=N, factor=factor, positive=pos, negative=W - pos)
        if all(t.cut_allowed(pos if t.side == 0 else W - pos, W) for t in tails) and (
                not _excess(response, v, plan)):
            return plan
        factor //= 2
    return None


def _resolution_cap(tails: list[Tail], N: int) -> int:
    """The largest factor that leaves each resonance the ``tails`` see at least
    :data:`KEPT_LINES_PER_BAND` kept lines across its half-power band: an energy decaying at
    ``rate`` per sample rings at ``rate / 2`` per sample in amplitude, a half-power band of
    ``N rate / (2 pi)`` of the ``N`` lines (a tail that fell within one block, ``rate``
    infinite, sets no cap; one with no decay fitted is refused by the cut anyway)."""
    widths = [N * t.rate / (2.0 * np.pi) for t in tails if np.isfinite(t.rate) and t.rate > 0]
    return N if not widths else int(min(widths) // KEPT_LINES_PER_BAND)


def compress(H: np.ndarray, plan: CompressionPlan) -> np.ndarray:
    """The FRFs ``(N, ...)`` (or records ``(R, N, ...)``) compressed by ``plan``: their
    cut response's FRF at the lines kept, ``(N // factor rounded up, ...)``."""
    a = np.asarray(H)
    if a.shape[0] != plan.n_lines:  # records: one set of FRFs each
        return np.stack([compress(r, plan) for r in a])
    response = _Response.of(a)
    cut = np.fft.fft(response.h * plan.window()[:, None], axis=0)[plan.kept]
    out = cut + _edge_cubic(response.ends, plan.n_lines, plan.kept)
    return out.reshape((plan.kept.size,) + a.shape[1:])


def compressed_variance(variance: np.ndarray, plan: CompressionPlan) -> np.ndarray:
    """The noise variance of :func:`compress`'s lines, for independent noise of
    ``variance`` (``(N, ...)``) on the band's lines: a compressed line is the sum of the
    lines weighted by the cut's kernel ``c`` (the DFT of the window over ``N``), so its
    variance is the circular convolution of ``|c|^2`` with ``variance`` (``sum |c|^2 =
    W / N``, about ``1 / factor``)."""
    v = _entries(np.asarray(variance, dtype=float))
    out = _window_convolved(v, plan)[plan.kept]
    floor = np.min(v, axis=0) * (plan.positive + plan.negative) / plan.n_lines
    out = np.maximum(out, floor[None, :])  # rounding of the convolution, never below
    return out.reshape((plan.kept.size,) + np.shape(variance)[1:])
