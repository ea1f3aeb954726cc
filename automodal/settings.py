"""The settings of one identification, checked when they are made.

:class:`Settings` is frozen and validated in ``__post_init__``: a bad value raises
:class:`SettingsError`, which names the field and the values allowed. It is an
:class:`~automodal.errors.InputError` (the command line prints one line and exits 2) and
a :class:`ValueError` (what a library caller expects of a bad argument).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from dataclasses import dataclass
from typing import Any

from automodal.errors import InputError

RESAMPLE_CHOICES = ("auto", "lines", "records", "noise")
"""What a bootstrap replicate may resample (see :attr:`Settings.resample`)."""

WEIGHTING_CHOICES = ("auto", "noise", "envelope")
"""How lines and channels are weighted (see :attr:`Settings.weighting`)."""

MIN_ORDER = 4
"""Smallest ``max_order``: the order scan needs orders 2 and 4 (the command line's
``--order`` has the same lower bound)."""

MIN_BLOCK_ROWS = 2
"""Smallest ``block_rows``: the shift invariance that gives ``A`` compares block rows
``1..q-1`` with ``2..q``, so it needs two."""


class SettingsError(InputError, ValueError):
    """A setting outside its allowed values (the message names the field)."""


def _is_int(value: Any) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _is_real(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _refuse(name: str, value: Any, allowed: str) -> SettingsError:
    return SettingsError(f"setting {name} = {value!r} is not allowed: it must be {allowed}")


@dataclass(frozen=True)
class Settings:
    """Every parameter that influences a run (all have automatic defaults).

    Every field is checked on creation (also by :func:`dataclasses.replace`); a bad value
    raises :class:`SettingsError` naming the field and the allowed values.

    Attributes
    ----------
    band_hz : (float, float) or None
        Analysed band, two finite numbers ``0 <= lo < hi``; default the data's span (a
        0 Hz line is left out). Stored as a tuple of floats.
    n_bootstrap : int
        Bootstrap replicates, at least 1 (the command line asks for at least 2).
    seed : int
        Seed of the resampling, ``>= 0``; the same seed gives the same result whatever
        ``jobs``.
    max_order : int or None
        Largest model order (states) considered, at least :data:`MIN_ORDER`; an odd value
        is rounded down to even. Default what the data allow.
    jobs : int or None
        Worker threads for the replicates, the sub-bands of a split band and the
        refinement's sums and tests, at least 1; ``None`` (the only "automatic" value) uses
        all cores when the work pays for them. Never changes the result.
    threshold : float
        ``tau_1``, the correlation a mode needs to join a cluster, in ``(0, 1]``.
    zeta_max : float
        Largest damping ratio of a physical candidate, in ``(0, 1)``.
    min_physicalness : float
        Physicalness from which a cluster is called physical, in ``(0, 1]`` (the vetoes and
        the refinement's tests give physicalness 0, which is never physical).
    coalescence : float
        Poles closer than this many half-power bandwidths form one group, ``> 0``.
    resample : {"auto", "lines", "records", "noise"}
        What a bootstrap replicate resamples: ``"auto"``, the repeated records when the
        data have at least two and their mean is as precise an estimate as the FRF
        (:func:`automodal.core.noise.mean_as_precise`; not for H1 of random force),
        else the frequency lines; ``"records"`` or ``"lines"`` always; ``"noise"``
        (needs the noise weighting) fresh noise of the noise model, times the reference
        model's dispersion, around the reference model's FRF (``docs/method.md`` 4 says
        why ``"auto"`` does not choose it).
    weighting : {"auto", "noise", "envelope"}
        ``"noise"``: lines and channels whitened by the noise model
        (:mod:`automodal.core.noise`), orders by a significance test of the whitened
        residual, physicalness on each mode's SNR; ``"envelope"``: the earlier
        stand-ins (envelope line weights, RMS channel scales, the misfit floor);
        ``"auto"`` (default): ``"noise"`` for FRFs, ``"envelope"`` for the half spectra of
        output-only (operational) data, whose errors are correlated across lines by the
        lag window, so the noise model's independent-line law does not hold (on the
        Weimar ambient record the noise path lost two of the 11 reference modes).
    sub_bands : bool
        Whether a band whose one model would be too costly (:mod:`automodal.core.sub_bands`)
        is split at the valleys between resonance peaks into sub-bands, each identified on
        its own, and the modes merged (not when ``max_order`` is given). The five LADISK
        hammer hits (10 000 lines, one output) took 114 s as one model of 256 states.
    block_rows : int or None
        At least this many block rows ``q`` in the reference model and its bootstrap
        replicates (in every sub-band; not in the first pass of output-only data, which
        only finds the modes), at least :data:`MIN_BLOCK_ROWS`; at most what a
        replicate's lines allow (:func:`automodal.core.order.block_row_budget`; the
        report warns when that cuts it). ``None`` (default): ``ceil(1.2 n / r) + 1`` for
        a reference of ``n`` states whose outputs show ``r`` directions above the noise.
        Many sensors on close modes need more: on an 8 x 10 grid seen by 40 sensors (80
        modes, 1 % noise) the sub-bands' references found 5 of 36 and 13 of 27 of their
        modes with the default ``q = 9`` and 34 and 27 with ``q = 18`` and 14
        (``benchmarks/results_sub_band_rows.md``). More rows cost time (a replicate's work
        grows as ``q^2``, its eigenvalues as ``q^3``) and make the split into sub-bands
        finer. Whatever it is, a band whose refinement cannot confirm a physical mode is
        analysed again at the order scan's rows when those are more (``docs/method.md``
        1), and the analysis confirming more physical modes is reported.
    """

    band_hz: tuple[float, float] | None = None
    n_bootstrap: int = 100
    seed: int = 0
    max_order: int | None = None
    jobs: int | None = None
    threshold: float = 0.8
    zeta_max: float = 0.2
    min_physicalness: float = 0.5
    coalescence: float = 1.0
    resample: str = "auto"
    weighting: str = "auto"
    sub_bands: bool = True
    block_rows: int | None = None

    def __post_init__(self) -> None:
        self._check_band()
        if not (_is_int(self.n_bootstrap) and self.n_bootstrap >= 1):
            raise _refuse("n_bootstrap", self.n_bootstrap, "an integer >= 1")
        if not (_is_int(self.seed) and self.seed >= 0):
            raise _refuse("seed", self.seed, "an integer >= 0")
        if self.max_order is not None and not (
            _is_int(self.max_order) and self.max_order >= MIN_ORDER
        ):
            raise _refuse("max_order", self.max_order,
                          f"None (automatic) or an integer >= {MIN_ORDER}")
        if self.jobs is not None and not (_is_int(self.jobs) and self.jobs >= 1):
            raise _refuse("jobs", self.jobs, "None (all cores) or an integer >= 1")
        self._check_interval("threshold", self.threshold, 0.0, 1.0, "a number in (0, 1]",
                             closed_hi=True)
        self._check_interval("zeta_max", self.zeta_max, 0.0, 1.0, "a number in (0, 1)")
        # above 0: a cluster that a veto, a split-resonance or a resolution test gave
        # physicalness 0 must not be physical
        self._check_interval("min_physicalness", self.min_physicalness, 0.0, 1.0,
                             "a number in (0, 1]", closed_hi=True)
        self._check_interval("coalescence", self.coalescence, 0.0, math.inf,
                             "a finite number > 0")
        if self.block_rows is not None and not (
            _is_int(self.block_rows) and self.block_rows >= MIN_BLOCK_ROWS
        ):
            raise _refuse("block_rows", self.block_rows,
                          f"None (automatic) or an integer >= {MIN_BLOCK_ROWS}")
        for name in ("max_order", "block_rows"):  # plain ints (numpy's do not go to JSON)
            if getattr(self, name) is not None:
                object.__setattr__(self, name, int(getattr(self, name)))
        if not isinstance(self.sub_bands, bool):
            raise _refuse("sub_bands", self.sub_bands, "True or False")
        if not (isinstance(self.resample, str) and self.resample in RESAMPLE_CHOICES):
            raise _refuse("resample", self.resample, "one of " + ", ".join(
                repr(c) for c in RESAMPLE_CHOICES))
        if not (isinstance(self.weighting, str) and self.weighting in WEIGHTING_CHOICES):
            raise _refuse("weighting", self.weighting, "one of " + ", ".join(
                repr(c) for c in WEIGHTING_CHOICES))
        if self.resample == "noise" and self.weighting == "envelope":
            raise _refuse("resample", self.resample,
                          "another choice than 'noise' when weighting is 'envelope'")

    def weighting_for(self, operational: bool) -> str:
        """The weighting a run uses: ``"noise"`` or ``"envelope"`` (``"auto"`` resolved:
        envelope for output-only half spectra, noise otherwise)."""
        if self.weighting != "auto":
            return self.weighting
        return "envelope" if operational else "noise"

    def _check_band(self) -> None:
        band = self.band_hz
        if band is None:
            return
        allowed = "None (the data's span) or two finite numbers lo, hi with 0 <= lo < hi"
        try:
            lo, hi = band
        except (TypeError, ValueError):
            raise _refuse("band_hz", band, allowed) from None
        if not (_is_real(lo) and _is_real(hi)):
            raise _refuse("band_hz", band, allowed)
        lo, hi = float(lo), float(hi)
        if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 <= lo < hi):
            raise _refuse("band_hz", band, allowed)
        object.__setattr__(self, "band_hz", (lo, hi))

    @staticmethod
    def _check_interval(name: str, value: Any, lo: float, hi: float, allowed: str,
                        closed_lo: bool = False, closed_hi: bool = False) -> None:
        ok = _is_real(value) and math.isfinite(float(value))
        if ok:
            v = float(value)
            ok = (v >= lo if closed_lo else v > lo) and (v <= hi if closed_hi else v < hi)
        if not ok:
            raise _refuse(name, value, allowed)

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form (``jobs`` left out: it never changes the result)."""
        d = dataclasses.asdict(self)
        d.pop("jobs")
        if d["band_hz"] is not None:
            d["band_hz"] = [float(x) for x in d["band_hz"]]
        return d
