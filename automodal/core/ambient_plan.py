"""The output-only analysis planned from a first identification: the band (decimation) and
the max lag of the half spectra (pure functions, no I/O).

Output-only data give no force spectrum to say where the information ends, and the
half spectra's one free choice, the max lag ``M`` (:func:`automodal.core.spectra.half_spectra`),
depends on the modes themselves. A first identification with default choices gives the
modes; from them:

* **Band** (:func:`decimation_factor`): the analysed band ends at :data:`BAND_MARGIN` (1.25)
  times the highest physical mode of the first pass (the FRF route's default band factor,
  see :mod:`automodal.core.simulate_time`), reached by decimating the records (low-pass
  filter, then every ``q``-th sample) so that the input stage's usable band
  ``fs / (2.56 q)`` still covers it. Why: the half spectra are fitted over every line of the
  band; a wide band of lines that hold no physical mode, or that hold modes above the
  ones wanted (the Weimar frame has one at 26.7 Hz), asks the model for states that fit
  them, and the lightly damped low modes get less of the fit. Measured on Weimar setup 1
  (11 reference modes up to 13.9 Hz, ``fs`` = 256 Hz, 4-7 s of lags): usable band 100 Hz
  (no decimation) 7 of 11 modes' damping within 30 % of the reference; 33 Hz (q = 3) 7-8;
  25 Hz (q = 4) 9; 20 Hz (q = 5, this rule) and 16.7 Hz (q = 6) 10.
* **Max lag** (:func:`lag_length`): ``M / fs = min(LAG_DECAYS / sigma_min, T /
  MIN_BLOCKS)``, with ``sigma_min`` the slowest decay rate ``zeta omega`` of the first
  pass's physical modes and ``T`` the record's duration. The half spectra are exactly
  rational whatever ``M`` (the lag window and the truncation only move the poles by a
  known amount and scale the residues), so ``M`` is a trade between variance and
  resolution, not a bias: the error of an estimated correlation does not decay with the
  lag while the structure's correlation does, so lags beyond a few decay times of the
  slowest mode add only noise (:data:`LAG_DECAYS` = 10), and each lag must be averaged over
  enough independent stretches of the record, ``T / M >= MIN_BLOCKS`` (48); at most
  :data:`MAX_LAG` (16384) lags, the line budget of the Welch segments. A record
  shorter than about 500 decay times of its slowest mode (Weimar setup 1: 4.6 of mode 1)
  is bound by ``T / MIN_BLOCKS``; a longer one by the decays.

Calibration (simulated ambient tests of ``automodal simulate``, the chain3, chain4,
chain6, grid3x2 and chain5np systems of ``tests/test_simulate_time.py``, seeds 1 and 2
only; the tests judge other seeds):

* at 2000 decay times, lags of 5-20 decay times gave every mode with damping errors of
  1-5 %; the former default (16384 samples, 40-140 decay times) gave two spurious extra
  modes on one system, lags under 2 decay times lost modes on two;
* at 60 and 150 decay times, ``T / M`` of 16, 24, 32 and 48 gave about the same (91, 87,
  91 and 86 of 96 modes' damping within 20 %: the sampling error of one short record, the
  errors scattering both ways), 64 a little worse (86, of which 42 of 48 at 150 decay
  times against 46-47 for the others);
* Weimar setup 1 (decimated by 5) was flat for ``T / M`` from 32 to 60 in damping (10 of
  11 modes within 30 % of the reference), but at 32 a spurious physical companion of mode 1
  appeared (1.233 Hz beside 1.229 Hz, in each of three seeds) and not at 40-60. Of the
  values the simulations could not tell apart, 48 was taken for that reason: the only
  constant of the rule chosen with the real data in view.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

__all__ = [
    "BAND_MARGIN",
    "LAG_DECAYS",
    "MIN_BLOCKS",
    "MIN_LAG",
    "MAX_LAG",
    "MAX_STAGE",
    "OperationalPlan",
    "decimation_factor",
    "decimation_stages",
    "lag_length",
    "plan_operational",
]

BAND_MARGIN = 1.25
"""Top of the analysed band over the highest physical mode of the first pass."""

LAG_DECAYS = 10.0
"""Most decay times ``1 / (zeta omega)`` of the slowest mode spanned by the lags."""

MIN_BLOCKS = 48
"""Fewest independent stretches of one max lag in the record (``T / M``)."""

MIN_LAG = 64
"""Fewest lags (samples): 32 lines up to the Nyquist frequency."""

MAX_LAG = 16384
"""Most lags (samples): the line budget of :func:`automodal.core.spectra.choose_segment`
(8193 lines; the identification's cost grows with the lines)."""

MAX_STAGE = 12
"""Largest decimation of one stage (scipy.signal.decimate advises below 13)."""

_STAGE_PRIMES = (2, 3, 5, 7)  # a larger decimation runs in stages made of these


@dataclass(frozen=True)
class OperationalPlan:
    """The choices of the output-only analysis (:func:`plan_operational`).

    Attributes
    ----------
    decimation : int
        Decimation factor ``q`` of the records (1: none).
    nperseg : int
        Max lag ``M`` of the half spectra, in samples of the decimated records.
    top_hz : float
        The band's top the decimation keeps (``BAND_MARGIN`` times the highest mode, or
        the band asked for).
    slowest_decay_per_s : float
        ``min zeta omega`` of the first pass's physical modes (1/s); NaN when none has a
        positive damping (the record alone then bounds the lags).
    """

    decimation: int
    nperseg: int
    top_hz: float
    slowest_decay_per_s: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly fields (a decay that is not known, NaN, as ``None``)."""
        return {k: (int(v) if isinstance(v, int) else float(v) if math.isfinite(v) else None)
                for k, v in asdict(self).items()}


def decimation_factor(sample_rate: float, top_hz: float, usable_fraction: float) -> int:
    """The largest decimation whose usable band still reaches ``top_hz``.

    Parameters
    ----------
    sample_rate : float
        Hz, of the records.
    top_hz : float
        The highest frequency to keep.
    usable_fraction : float
        Fraction of the Nyquist band the input stage keeps (``fs / 2.56``: 1 / 1.28).

    Returns
    -------
    int
        ``q >= 1`` with ``usable_fraction * sample_rate / (2 q) >= top_hz``, the largest such;
        above :data:`MAX_STAGE` it runs in stages (:func:`decimation_stages`) and is stepped
        down to a number whose prime factors are at most 7.
    """
    if not (sample_rate > 0 and top_hz > 0 and 0 < usable_fraction <= 1):
        raise ValueError("sample_rate, top_hz and usable_fraction must be positive")
    q = max(1, int(math.floor(usable_fraction * sample_rate / (2.0 * top_hz) + 1e-9)))
    while q > MAX_STAGE and not _smooth(q):
        q -= 1
    return q


def decimation_stages(q: int) -> list[int]:
    """``q`` as a product of stage factors of at most :data:`MAX_STAGE` (12), fewest stages
    (each stage's filter adds its own ripple), largest first.

    Raises
    ------
    ValueError
        If ``q`` above 12 has a prime factor above 7.
    """
    q = int(q)
    if q < 1:
        raise ValueError(f"decimation must be >= 1, got {q}")
    if q <= MAX_STAGE:
        return [] if q == 1 else [q]
    if not _smooth(q):
        raise ValueError(f"decimation {q} has a prime factor above 7")
    primes = []
    for p in _STAGE_PRIMES:
        while q % p == 0:
            primes.append(p)
            q //= p
    stages: list[int] = []
    for p in sorted(primes, reverse=True):  # first fit of the factors into stages
        for i, st in enumerate(stages):
            if st * p <= MAX_STAGE:
                stages[i] = st * p
                break
        else:
            stages.append(p)
    return sorted(stages, reverse=True)


def _smooth(q: int) -> bool:
    for p in _STAGE_PRIMES:
        while q % p == 0:
            q //= p
    return q == 1


def lag_length(
    n_samples: int,
    sample_rate: float,
    slowest_decay: float | None,
    *,
    decays: float = LAG_DECAYS,
    min_blocks: int = MIN_BLOCKS,
    min_lag: int = MIN_LAG,
    max_lag: int = MAX_LAG,
) -> int:
    """Max lag ``M`` (samples) of the half spectra: ``min(decays / sigma, T / min_blocks)``.

    Parameters
    ----------
    n_samples : int
        Samples in the (decimated) record.
    sample_rate : float
        Its rate, Hz.
    slowest_decay : float or None
        ``min zeta omega`` of the modes (1/s); ``None`` or not positive: the record's
        bound alone.
    decays, min_blocks, min_lag, max_lag : see :data:`LAG_DECAYS`, :data:`MIN_BLOCKS`,
        :data:`MIN_LAG`, :data:`MAX_LAG`.

    Returns
    -------
    int
        ``M``, in ``[min_lag, max_lag]`` and below half the record.
    """
    if n_samples < 4:
        raise ValueError(f"the record ({n_samples} samples) is too short")
    m = n_samples / float(min_blocks)
    if slowest_decay is not None and np.isfinite(slowest_decay) and slowest_decay > 0:
        m = min(m, decays * sample_rate / slowest_decay)
    return int(min(max(int(round(m)), min_lag), max_lag, n_samples // 2))


def plan_operational(
    n_samples: int,
    sample_rate: float,
    frequency_hz: np.ndarray,
    damping_ratio: np.ndarray,
    usable_fraction: float,
    band_top_hz: float | None = None,
) -> OperationalPlan:
    """Decimation and max lag from a first pass's physical modes.

    Parameters
    ----------
    n_samples, sample_rate : int, float
        The records as measured.
    frequency_hz, damping_ratio : ndarray
        The first pass's physical modes (at least one with a finite frequency > 0).
    usable_fraction : float
        Fraction of the Nyquist band the input stage keeps.
    band_top_hz : float, optional
        A band asked for: its top replaces ``BAND_MARGIN`` times the highest mode (and the
        modes above it do not set the lags).

    Returns
    -------
    OperationalPlan
        The decimation is :func:`decimation_factor`'s, but at most ``n_samples //
        (MIN_BLOCKS * MIN_LAG)`` (a record too short for it is decimated less, so that
        ``MIN_BLOCKS`` stretches of ``MIN_LAG`` lags remain).
    """
    f = np.asarray(frequency_hz, dtype=float).ravel()
    z = np.asarray(damping_ratio, dtype=float).ravel()
    ok = np.isfinite(f) & (f > 0) & np.isfinite(z)
    if band_top_hz is not None:
        ok &= f <= band_top_hz
    if not ok.any():
        raise ValueError("no mode to plan the analysis from")
    f, z = f[ok], z[ok]
    top = float(band_top_hz) if band_top_hz is not None else BAND_MARGIN * float(f.max())
    q = decimation_factor(sample_rate, top, usable_fraction)
    # a short record keeps MIN_BLOCKS stretches of MIN_LAG samples after decimation
    q = min(q, max(1, n_samples // (MIN_BLOCKS * MIN_LAG)))
    while q > MAX_STAGE and not _smooth(q):
        q -= 1
    sigma = z * 2.0 * np.pi * f
    sigma = sigma[sigma > 0]
    slowest = float(sigma.min()) if sigma.size else float("nan")
    m = lag_length(n_samples // q, sample_rate / q, slowest if sigma.size else None)
    return OperationalPlan(decimation=q, nperseg=m, top_hz=top, slowest_decay_per_s=slowest)
