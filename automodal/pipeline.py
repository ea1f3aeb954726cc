"""The automated pipeline: from a test to identified modes with physicalness.

Orchestration only; each step is one call into the numerical core (``method.md``
sections 1-6):

1. input stage and preparation (:func:`prepare`): band, data checks
   (:func:`automodal.core.checks.prepare`), reciprocity, bilinear map, channel scaling,
   line weights;
2. orders (:func:`automodal.core.order.select_orders`): misfit scan, ``n0`` and the
   excessive reference order;
3. reference model (:func:`automodal.core.reference.build_reference`): identified once,
   decomposed once, its candidates and coalescent groups;
4. bootstrap replicates (:mod:`automodal.core.replicates`): A and C only, batched Gram
   sums, stacked small problems in parallel threads;
5. clustering (:func:`automodal.core.reference.cluster_against_reference`): one-pass
   assignment with a Trashbox, trimming;
6. physicalness and statistics (:func:`automodal.core.summary.summarise_clusters`);
7. the physical modes' poles refined by noise-weighted maximum likelihood, with
   Cramér-Rao intervals (:func:`automodal.core.summary.refine_physical_modes`), and the
   FRF of the physical modes.

:class:`Settings` lives in :mod:`automodal.settings`, :class:`Result`,
:class:`IdentifiedMode` and :class:`PoleTable` in :mod:`automodal.result`; they are
imported here too.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from automodal.band_merge import merge_sub_bands
from automodal.core import (
    bootstrap,
    checks,
    order,
    parallel,
    physicalness,
    reference,
    replicates,
    stabilization,
    sub_bands,
    subspace,
    summary,
    synthesis,
    whitening,
)
from automodal.core.bilinear import default_scale, to_unit_circle
from automodal.core.clustering import TRASHBOX
from automodal.core.from_time import as_frfdata
from automodal.core.modal import pole_damping_ratio
from automodal.core.pole_map import PoleMap
from automodal.core.reciprocity import apply_reciprocity
from automodal.core.summary import RESOLUTION_DECAY, local_spacing, resolved
from automodal.errors import InputError
from automodal.frfdata import FRFData
from automodal.progress import ProgressCallback, counter, tell, within
from automodal.quantities import quantity_power
from automodal.result import IdentifiedMode, NoiseInfo, PoleTable, Result
from automodal.settings import Settings

if TYPE_CHECKING:
    from automodal.core.noise import NoiseEstimate
    from automodal.timedata import TimeSeries

__all__ = [
    "IdentifiedMode",
    "PoleTable",
    "Prepared",
    "Result",
    "Settings",
    "identify",
    "input_stage",
    "prepare",
    "select_band",
]


# ---------------------------------------------------------------------------------------
# Input stage and preparation
# ---------------------------------------------------------------------------------------


def select_band(
    data: FRFData, band_hz: tuple[float, float] | None, warnings: list[str]
) -> tuple[np.ndarray, np.ndarray, tuple[float, float]]:
    """Lines of the analysed band (a 0 Hz line is always left out)."""
    f = data.frequency
    lo, hi = (float(f[0]), float(f[-1])) if band_hz is None else map(float, band_hz)
    if band_hz is not None and not (0 <= lo < hi):
        raise InputError(f"band [{lo:g}, {hi:g}] Hz is not a valid band", data.source)
    keep = (f >= lo) & (f <= hi) & (f > 0)
    if band_hz is None and f[0] == 0:
        warnings.append("the 0 Hz line was left out of the analysis")
    if not keep.any():
        raise InputError(f"no frequency line in the band [{lo:g}, {hi:g}] Hz (the data's "
                         f"lines span [{f[0]:g}, {f[-1]:g}] Hz)", data.source)
    fk = f[keep]
    first = f[f > 0][0]
    if band_hz is not None and (0 < lo < first or hi > f[-1]):  # 0: "from the start"
        warnings.append(f"the band [{lo:g}, {hi:g}] Hz reaches beyond the data's lines "
                        f"[{first:g}, {f[-1]:g}] Hz: the band analysed is "
                        f"[{fk[0]:g}, {fk[-1]:g}] Hz")
    return fk, data.frf[keep], (float(fk[0]), float(fk[-1]))


@dataclass
class Prepared:
    """The analysed data, ready for identification (see :func:`prepare`)."""

    data: FRFData  # after the checks (channels or lines may have been dropped)
    frequency: np.ndarray  # analysed lines, Hz
    H: np.ndarray  # analysed FRF, oriented for identification (reciprocity applied)
    band_hz: tuple[float, float]
    reciprocal: bool
    omega: np.ndarray  # lines at which the model is fitted, rad/s (prewarped when sampled)
    T: float  # bilinear scale
    z: np.ndarray  # lines on the unit circle
    scales: np.ndarray  # per-output scaling (noise std, or RMS without a noise model)
    Hs: np.ndarray  # scaled FRF
    line_weights: np.ndarray
    noise: NoiseEstimate | None = None  # the noise model of the analysed FRF (un-oriented)
    variance: np.ndarray | None = None  # its variance, oriented and channel-scaled like Hs,
    # when the identification is weighted by it (weighting "noise")
    factor: np.ndarray | None = None  # (N,): H is the receptance form H_model times this
    # (synthesis.quantity_factor; None: the FRF is identified as it is)

    @property
    def H_model(self) -> np.ndarray:
        """The FRF in the form the subspace models fit (``Hs`` before channel scaling): the
        receptance form of a mobility or accelerance, else ``H``."""
        return _in_model_form(self.H, self.factor)

    @property
    def weighting(self) -> str:
        """The weighting in force: ``"noise"`` (whitened by the noise model) or
        ``"envelope"``."""
        return "envelope" if self.variance is None else "noise"

    def enveloped(self) -> Prepared:
        """The same preparation with envelope line weights and RMS channel scales (the
        noise model kept for the intervals)."""
        scales, Hs, weights, _ = _weighted(self.H_model, None)
        return replace(self, scales=scales, Hs=Hs, line_weights=weights, variance=None)

    @property
    def noise_variance(self) -> np.ndarray | None:
        """The noise variance oriented like ``H`` (data units), or ``None``."""
        return None if self.noise is None else _oriented(self.noise.variance, self.reciprocal)

    @property
    def model_noise_variance(self) -> np.ndarray | None:
        """The noise variance of :attr:`H_model` (data units over ``|factor|^2``), or
        ``None``."""
        v = self.noise_variance
        return None if v is None else _in_model_form(v, self.factor, True)

    pole_map: PoleMap = field(default_factory=PoleMap)  # model poles -> the structure's

    @property
    def band_rad_s(self) -> tuple[float, float]:
        """The analysed band in rad/s (of the structure, not prewarped)."""
        return 2.0 * np.pi * float(self.frequency[0]), 2.0 * np.pi * float(self.frequency[-1])


def prepare(
    data: FRFData, s: Settings, warnings: list[str], receptance: bool | None = None
) -> Prepared:
    """Band, data checks, reciprocity, bilinear map, channel scaling and line weights.

    The first steps of :func:`identify`, also used by the benchmarks so that they time
    exactly what the pipeline runs. Warnings are appended to ``warnings``. ``receptance``:
    whether a mobility or accelerance is identified in its receptance form; ``None``
    chooses (:func:`automodal.core.checks.identified_form`), a sub-band keeps its band's
    choice.
    """
    freq, H, band = select_band(data, s.band_hz, warnings)
    operational = data.output_only
    power = _power(data)
    data, freq, H, flatter = checks.prepare(data, freq, H, warnings, power)
    noise = None
    try:
        noise = _estimate_noise(data, freq, H)
        warnings.extend(noise.conflicts)
    except ValueError as exc:  # too few lines for the local polynomial
        warnings.append(f"no noise model ({exc}): envelope line weights and RMS scales,"
                        " bootstrap intervals")
    if noise is not None and not operational:
        data, freq, H, noise = _compressed(data, freq, H, noise, warnings, s.max_order)
    H, reciprocal = apply_reciprocity(H, warnings)
    pole_map = pole_map_of(data)
    if pole_map.shift > 2.0 * np.pi * freq[-1]:
        # the window adds a to every mode's decay rate: every mode of the band would be
        # damped beyond zeta = 0.7 in the data, where no resonance is left to identify
        raise InputError(
            f"attribute window_decay_per_s = {pole_map.shift:g} 1/s is more than the band's"
            f" top angular frequency ({2.0 * np.pi * freq[-1]:.4g} rad/s): such a window"
            " would leave no resonance in the band; give the window's decay in 1/s",
            data.source)
    try:
        omega = pole_map.model_omega(2.0 * np.pi * freq)
    except ValueError as exc:
        raise InputError(f"attribute discrete_sample_rate_hz: {exc}", data.source) from None
    T = default_scale(omega[0], omega[-1])
    weighting = s.weighting_for(operational)
    # a mobility or an accelerance may be flatter in its receptance form: the models then
    # need not reproduce the trend (an accelerance's rise from 0 Hz)
    factor = synthesis.quantity_factor(2.0 * np.pi * freq, power, pole_map.shift) if (
        flatter if receptance is None else receptance) and power > 0 else None
    variance = None
    if noise is not None and weighting == "noise":
        variance = _in_model_form(_oriented(noise.variance, reciprocal), factor, True)
    scales, Hs, weights, variance = _weighted(_in_model_form(H, factor), variance)
    return Prepared(
        data=data, frequency=freq, H=H, band_hz=band, reciprocal=reciprocal, omega=omega, T=T,
        z=to_unit_circle(omega, T), scales=scales, Hs=Hs, line_weights=weights,
        noise=noise, variance=variance, factor=factor, pole_map=pole_map,
    )


def _compressed(
    data: FRFData, freq: np.ndarray, H: np.ndarray, noise: NoiseEstimate,
    warnings: list[str], max_order: int | None,
) -> tuple[FRFData, np.ndarray, np.ndarray, NoiseEstimate]:
    """The band in fewer lines where its responses end long before its lines' record does
    (:mod:`automodal.core.line_compression`): ``data`` (the band's lines only, its records
    compressed alike and its coherence, already read into ``noise``, left out), lines, FRFs
    and noise (the variance propagated; the levels stay the measurement's); or all as they
    are. At least the lines every automatic order needs are kept
    (:func:`automodal.core.order.lines_for_orders`; ``max_order``: the settings')."""
    from automodal.core import line_compression

    plan = line_compression.plan_compression(
        freq, H, noise.variance, order.lines_for_orders(*H.shape[1:], max_order))
    if plan is None:
        return data, freq, H, noise
    kept = freq[plan.kept]
    lines = _file_lines(data, freq)
    records = None if data.records is None or lines is None else (
        line_compression.compress(data.records[:, lines], plan))
    df = (freq[-1] - freq[0]) / (freq.size - 1)
    note = (f"{freq.size} lines {df:.3g} Hz apart compressed to {kept.size}"
            f" ({kept[1] - kept[0]:.3g} Hz apart): the impulse response over the band,"
            " cut to its first"
            f" {plan.positive / (freq.size * df):.3g} s (at least twice as long as it stands"
            " out of the noise), then back to every"
            f" {plan.factor}-th line; each line's noise variance is about 1/{plan.factor} of"
            " the measured lines'")
    warnings.append(f"the band has {note}")
    noise = replace(noise, variance=line_compression.compressed_variance(noise.variance, plan),
                    assumptions=noise.assumptions + (note,))
    data = replace(data, frequency=kept, frf=line_compression.compress(H, plan),
                   coherence=None, records=records)
    return data, kept, data.frf, noise


def _power(data: FRFData) -> int:
    """The FRFs are a receptance times ``(j w)^power`` (0 receptance, 1 mobility, 2
    accelerance); output-only half spectra have the pole-residue form as they are (0)."""
    return 0 if data.output_only else quantity_power(data.quantity)


def pole_map_of(data: FRFData) -> PoleMap:
    """How the model's poles become the structure's, from the data's attributes:
    ``window_decay_per_s`` (an exponential window's decay, 1/s) and
    ``discrete_sample_rate_hz`` (the FRFs are spectra of sampled signals, rational in
    ``exp(j 2 pi f / fs)``: the half spectra of output-only data).

    Raises
    ------
    InputError
        If either attribute is not a finite number (the rate: positive).
    """
    attrs = data.attributes
    decay, rate = attrs.get("window_decay_per_s"), attrs.get("discrete_sample_rate_hz")
    try:
        return PoleMap(shift=float(decay or 0.0),
                       sample_rate=None if rate is None else float(rate))
    except (TypeError, ValueError) as exc:
        raise InputError(f"attributes window_decay_per_s / discrete_sample_rate_hz: {exc}",
                         data.source) from None


def _weighted(
    H: np.ndarray, variance: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """Channel scales, scaled FRF, line weights and the channel-scaled variance: whitened by
    the noise ``variance`` (oriented like ``H``), or envelope weights and RMS scales when
    it is ``None``."""
    if variance is None:
        scales = subspace.channel_scales(H)
        Hs = H / scales[None, :, None]
        return scales, Hs, subspace.envelope_weights(Hs), None
    weights, scales = whitening.whitening(variance)
    return (scales, H / scales[None, :, None], weights,
            variance / (scales**2)[None, :, None])


def _in_model_form(
    a: np.ndarray, factor: np.ndarray | None, variance: bool = False
) -> np.ndarray:
    """Lines of ``a`` (``(N, ny, nu)``) divided by ``factor`` (:attr:`Prepared.factor`), or
    by ``|factor|^2`` for a ``variance``; ``a`` itself when ``factor`` is ``None``."""
    if factor is None:
        return a
    return a / (np.abs(factor) ** 2 if variance else factor)[:, None, None]


def _oriented(a: np.ndarray, reciprocal: bool) -> np.ndarray:
    """A per-entry array (``(..., outputs, inputs)``) in the other orientation: the data's
    in the analysed one, or back (inputs and outputs swapped under reciprocity; the swap is
    its own inverse)."""
    return np.swapaxes(a, -1, -2) if reciprocal else a


def _independent_lines(data: FRFData) -> bool:
    """Whether the data's errors are independent from line to line, as the likelihood of
    the refinement (:func:`automodal.core.summary.refine_physical_modes`) assumes.

    Not for half spectra (output-only data): the errors of a correlation estimate persist
    from lag to lag while a mode's correlation rings (Bartlett's formula), so near each
    resonance the half spectra's errors are smooth across lines and look like a moved
    resonance. The fit's residual then hides them and the likelihood counts each line as
    new evidence: on simulated ambient tests (5 systems, seeds 54-61, 192 modes) the
    refinement's 95 % intervals held the true frequency for 62 % of the modes and the
    true damping for 68 %, and its likelihood-ratio test kept spurious companions. The
    bootstrap over the half spectra's records (:func:`automodal.core.spectra.
    half_spectrum_records`) resamples the error as it is: 90 % and 91 % there, with no
    spurious mode. So output-only modes keep their bootstrap statistics."""
    return not data.output_only


def _file_lines(data: FRFData, freq: np.ndarray) -> np.ndarray | None:
    """Which of the file's lines are the band's ``freq``, or ``None`` when some of them
    are not lines of the file (its records and coherence then do not describe them)."""
    lines = np.isin(data.frequency, freq)
    return lines if int(lines.sum()) == freq.size else None


def _estimate_noise(data: FRFData, freq: np.ndarray, H: np.ndarray) -> NoiseEstimate:
    """The noise model of the analysed band (records, coherence or the data alone)."""
    from automodal.core.noise import averages_from_attributes, estimate_noise

    lines = _file_lines(data, freq)
    coh = None if data.coherence is None or lines is None else data.coherence[lines]
    rec = None if data.records is None or lines is None else data.records[:, lines]
    return estimate_noise(H, coherence=coh, records=rec,
                          n_averages=averages_from_attributes(data.attributes))


# ---------------------------------------------------------------------------------------
# The whole run
# ---------------------------------------------------------------------------------------


def identify(
    data: FRFData | TimeSeries,
    settings: Settings | None = None,
    progress: ProgressCallback | None = None,
) -> Result:
    """Identify the modes of a test, with no human choice.

    Parameters
    ----------
    data : FRFData or TimeSeries
        The test: FRFs, or time series that the input stage turns into FRFs.
    settings : Settings, optional
        Overrides of the automatic choices.
    progress : callable, optional
        Called with a :class:`~automodal.progress.Progress` (stage, done, total, part) as
        each stage starts and as the bootstrap replicates finish; it never changes the
        result.

    Returns
    -------
    Result
    """
    s = settings or Settings()
    # One BLAS thread for the many small dense problems (measured: 0.75 s against 0.9 s
    # end to end on a 6-DOF chain, and far steadier on a busy machine); the replicates
    # share the cores through worker threads (automodal.core.parallel).
    with parallel.blas_threads(1):
        data = input_stage(data, s, progress)  # time series become FRFs here
        return _identify(data, s, progress)


FIRST_PASS_MAX_LAG = 1024
"""Most lags of the output-only first pass: 513 lines, the resolution floor of
:func:`~automodal.core.spectra.choose_segment`; the first pass has only to find the modes,
and fewer lines make it quicker."""

FIRST_PASS_REPLICATES = 20
"""Bootstrap replicates of the output-only first pass (it only has to tell the physical
modes apart; their values are not reported)."""


def input_stage(
    data: FRFData | TimeSeries, settings: Settings | None = None,
    progress: ProgressCallback | None = None,
) -> FRFData:
    """The test as the FRFs the identification analyses.

    FRFs pass unchanged; time series with measured forces go through
    :func:`~automodal.core.from_time.as_frfdata` (H1). Output-only time series are analysed
    twice: a first identification of half spectra (the records as they are, max lag
    ``T / MIN_BLOCKS``, at most :data:`FIRST_PASS_MAX_LAG`, :data:`FIRST_PASS_REPLICATES`
    replicates) gives the physical modes, from which
    :func:`~automodal.core.ambient_plan.plan_operational` chooses the decimation (band to
    1.25 times the highest mode, or the band asked for) and the max lag (10 decay times of
    the slowest mode, at most ``T / MIN_BLOCKS``, :data:`~automodal.core.ambient_plan.
    MIN_BLOCKS` = 48); the half spectra are made again with them. Why,
    with the measurements: :mod:`automodal.core.ambient_plan`. The plan and the first
    pass's modes go in ``attributes["time_analysis"]["plan"]``. Without a physical mode in
    the first pass, its half spectra are kept (and the plan says so). ``progress`` as in
    :func:`identify` (the first pass's stages with the part ``"first pass"``).
    """
    from automodal.timedata import TimeSeries

    if not isinstance(data, TimeSeries) or data.inputs is not None:
        if isinstance(data, TimeSeries):
            tell(progress, "spectra")
        return as_frfdata(data)
    from automodal.core import ambient_plan
    from automodal.core.from_time import USABLE_FRACTION

    s = settings or Settings()
    m0 = min(FIRST_PASS_MAX_LAG,
             ambient_plan.lag_length(data.n_samples, data.sample_rate, None))
    first_pass = within(progress, "first pass")
    tell(first_pass, "spectra")
    first = as_frfdata(data, nperseg=m0)
    with parallel.blas_threads(1):
        # the first pass only finds the modes (its warnings are not kept): the automatic
        # block rows serve it, whatever block_rows the analysis asks for
        first_result = _identify(first, replace(s, n_bootstrap=min(
            s.n_bootstrap, FIRST_PASS_REPLICATES), block_rows=None), first_pass)
    phys = [m for m in first_result.modes if m.physical and np.isfinite(m.frequency_hz)]
    f = np.array([m.frequency_hz for m in phys], dtype=float)
    z = np.array([m.damping_ratio for m in phys], dtype=float)
    top = None if s.band_hz is None else float(s.band_hz[1])
    try:
        plan = ambient_plan.plan_operational(data.n_samples, data.sample_rate, f, z,
                                             USABLE_FRACTION, top)
    except ValueError:
        first.attributes["time_analysis"]["plan"] = {
            "first_pass_modes_hz": [], "note": "no physical mode in a first pass: its"
            " half spectra are analysed"}
        return first
    tell(progress, "spectra")
    out = as_frfdata(data, nperseg=plan.nperseg, decimation=plan.decimation)
    out.attributes["time_analysis"]["plan"] = {
        **plan.to_dict(), "first_pass_modes_hz": [float(x) for x in f],
        "first_pass_damping": [float(x) for x in z], "first_pass_nperseg": int(m0)}
    return out


def _identify_sub_bands(
    data: FRFData, s: Settings, plan: list[sub_bands.SubBand], warnings: list[str],
    progress: ProgressCallback | None, t0: float, order_of_whole: int,
    part: bool = False, receptance: bool | None = None, settled: bool = True,
) -> Result:
    """One identification per sub-band of ``plan``, side by side on the workers, merged
    (:func:`automodal.band_merge.merge_sub_bands`); ``warnings`` are the whole band's so
    far, ``t0`` when the run started, ``order_of_whole`` the reference order one model of
    the band would have had (``settled``: whether the band's scan ran to its end rather than
    stopping for the split), ``part`` and ``receptance`` (the band's form, kept by its
    sub-bands) as in :func:`_identify`."""
    def one(i: int, b: sub_bands.SubBand) -> Callable[[ProgressCallback | None], Result]:
        return lambda sent: _identify(
            data, replace(inner, band_hz=b.analysed_hz),
            within(sent, f"sub-band {i} of {len(plan)}"),
            part=True, parent_order=order_of_whole, receptance=receptance,
            parent_settled=settled)

    # the sub-bands are independent problems (each is the same whatever runs beside it, and
    # whatever its jobs) and run side by side, their progress in sub-band order; jobs asked
    # for are shared among them, and the automatic choice inside each takes the cores the
    # others leave (parallel.free_cores)
    n_jobs = parallel.worker_count(s.jobs, len(plan))
    inner = s if s.jobs is None else replace(s, jobs=max(1, s.jobs // n_jobs))
    results = parallel.relayed_map([one(i, b) for i, b in enumerate(plan, 1)], n_jobs, progress)
    if any(r.shape_channels != results[0].shape_channels for r in results):
        # the data checks dropped different channels in different sub-bands: the shapes
        # cannot be put side by side, so the band is identified as one
        return _identify(data, replace(s, sub_bands=False), progress, part,
                         receptance=receptance)
    merged = merge_sub_bands(results, plan, s.to_dict(), warnings, 0.0)
    if not part:  # a part's split is said by the whole band's run, once
        leaves = _leaf_orders(merged.orders)
        merged.warnings.append(_split_warning(
            (plan[0].analysed_hz[0], plan[-1].analysed_hz[1]), len(plan), len(leaves),
            order_of_whole, settled))
        merged.warnings.extend(_directions_warning(merged.orders, len(merged.shape_channels)))
        lines = merged.frf_fit[0] if merged.frf_fit is not None else data.frequency
        merged.warnings.extend(mode_warnings(merged.modes, lines, pole_map_of(data).shift))
    merged.runtime_s = time.perf_counter() - t0
    return merged


def _leaf_orders(orders: dict) -> list[dict]:
    """The orders of the bands a run identified (``Result.orders``): its own, or, for a
    band split into sub-bands, those of each sub-band's, followed into sub-bands split
    again, in frequency order."""
    parts = orders.get("sub_bands")
    if not parts:
        return [orders]
    return [leaf for part in parts for leaf in _leaf_orders(part)]


def _directions_warning(orders: dict, n_outputs: int) -> list[str]:
    """The principal-directions warning (:func:`_principal_warning`) of a run whose orders
    are ``orders`` (``Result.orders``; a split band's, over its sub-bands), or none where
    every band's replicates used all ``n_outputs`` outputs."""
    leaves = _leaf_orders(orders)
    directions = [d for d in (o.get("replicate_directions") for o in leaves) if d is not None]
    if not directions:
        return []
    return [_principal_warning(directions, n_outputs, len(leaves) if len(leaves) > 1 else None)]


def _split_warning(band_hz: tuple[float, float], n_first: int, n_leaves: int,
                   order_of_whole: int, settled: bool) -> str:
    """The warning that ``band_hz`` was identified in ``n_leaves`` sub-bands (``n_first`` at
    the first split, the rest where a part was split again), one model of it having
    ``order_of_whole`` states (``settled``: where its order scan ran to its end, else where
    the scan stopped for the split)."""
    again = (f" ({n_first} at first, then parts split again where one model of a part"
             " still cost too much)" if n_leaves > n_first else "")
    size = (f"one model of it would have had {order_of_whole} states" if settled else
            f"its order scan stopped for the split at {order_of_whole} states")
    return (f"[{band_hz[0]:g}, {band_hz[1]:g}] Hz was identified in {n_leaves} sub-bands"
            f"{again}, cut at valleys between resonances ({size}); settings.orders.sub_bands"
            " gives each sub-band's band and orders; --one-band (sub_bands=False) or --order"
            " keeps one model")


def _noise_of_scaled(noise_weighted: Prepared, p: Prepared) -> np.ndarray | None:
    """The noise variance of ``p.Hs`` when the run is weighted by the noise model, also
    where the order scan fell back on the envelope weighting (``p`` is then
    ``noise_weighted.enveloped()``, whose channels are scaled otherwise), else ``None``."""
    if noise_weighted.variance is None:
        return None
    ratio = noise_weighted.scales / p.scales
    return noise_weighted.variance * (ratio**2)[None, :, None]


def _choose_orders(
    p: Prepared, s: Settings, rank: int | None, split_work: float | None, warnings: list[str],
    reference_cap: int | None = None, stages: dict | None = None,
) -> tuple[Prepared, order.OrderChoice]:
    """The order scan's choice on the noise weighting, or on the envelope weighting when no
    model is near the data in the noise's terms (the data then prepared for it; the
    warning said once). ``rank``, ``split_work``, ``reference_cap`` (a sub-band's: its
    band's reference order) and ``stages`` (a dict kept by the caller for every call on
    ``p``) as for :func:`automodal.core.order.select_orders`."""
    choice = order.select_orders(p.z, p.Hs, p.line_weights, s.max_order, p.data.source,
                                 variance=p.variance, rank=rank, split_work=split_work,
                                 reference_cap=reference_cap, stages=stages,
                                 jobs=s.jobs, min_block_rows=s.block_rows)
    if p.variance is not None and choice.rule == "floor":
        # the noise weighting gives the order test nothing to stand on, so the envelope path
        # runs instead
        message = ("no scanned model fitted the noise-whitened data to the noise, and the"
                   " misfit still fell beyond the order the significance test chose: envelope"
                   " weighting and the misfit-floor order used")
        if message not in warnings:
            warnings.append(message)
        p = p.enveloped()
        noise_complete = choice.complete
        choice = order.select_orders(p.z, p.Hs, p.line_weights, s.max_order, p.data.source,
                                     rank=rank, split_work=split_work,
                                     reference_cap=reference_cap, stages=stages,
                                     jobs=s.jobs, min_block_rows=s.block_rows)
        # a noise scan cut short might have ended otherwise had it gone on
        choice = replace(choice, complete=choice.complete and noise_complete)
    return p, choice


def _identify(
    data: FRFData, s: Settings, progress: ProgressCallback | None, part: bool = False,
    parent_order: int | None = None, receptance: bool | None = None,
    parent_settled: bool = True,
) -> Result:
    """:func:`identify` with BLAS limited by the caller (``part``: one sub-band of a split
    band, whose modes' resolution warnings the merged result gives; ``parent_order``: the
    reference order of the band it was split from, which, where that band's scan ran to its
    end (``parent_settled``), caps its own and which its own must be below for it to be
    split again (a scan the split rule ended early stopped at an order that had not
    settled: no bound on a part of the band, ``docs/method.md`` 2.1); ``receptance``: the
    form identified, as for :func:`prepare`; a sub-band keeps its band's, chosen on the
    band's whole magnitude trend rather than on a part of it cut beside a peak)."""
    t0 = time.perf_counter()
    analysis = data.attributes.get("time_analysis")
    warnings: list[str] = [] if part or not isinstance(analysis, dict) else list(
        analysis.get("warnings", []))  # the input stage's (hits dropped)
    tell(progress, "checks")
    # a sub-band's data checks repeat the whole band's, and its edges are our cuts: its
    # warnings about them (an edge on a resonance, no peak) would only mislead
    p = prepare(data, s, [] if part else warnings, receptance)
    rank = None if p.variance is None else whitening.output_rank(p.Hs, p.variance)
    split_work = sub_bands.WORK_LIMIT if s.sub_bands and s.max_order is None else None
    tell(progress, "orders")
    prepared = p
    stages: dict = {}  # the scan's stages, for a rescan below
    cap = parent_order if parent_settled else None
    p, choice = _choose_orders(prepared, s, rank, split_work, warnings, cap, stages)
    wanted = n_bands = 1
    if s.sub_bands and s.max_order is None and (cap is None or choice.reference < cap):
        # a part is split again only when splitting made its model smaller: where the order
        # comes from the noise and the lines rather than the modes (a 9-DOF chain over 51 201
        # lines: a 0.2 Hz sub-band with one mode still took 112 states), splitting again
        # only multiplies the scans
        wanted = sub_bands.sub_band_count(sub_bands.replicate_work(
            *p.Hs.shape, choice.reference, choice.block_rows))
    if wanted > 1 and sub_bands.split_pays(
            *p.Hs.shape, choice.n0, choice.reference, choice.block_rows,
            order.reference_factor(choice.rule), wanted):
        n_bands = wanted
    if n_bands > 1:
        plan = sub_bands.plan_sub_bands(
            p.frequency, p.Hs, n_bands, stabilization.stable_frequencies(
                choice.models, p.T, p.band_hz, s.zeta_max, p.pole_map),
            _noise_of_scaled(prepared, p))
        if len(plan) > 1:  # a sub-band too costly is split again in its own run
            return _identify_sub_bands(data, s, plan, warnings, progress, t0,
                                       choice.reference, part, p.factor is not None,
                                       choice.complete)
    if (split_work is not None and not choice.complete
            and (wanted > 1 or choice.reference >= (parent_order or 0) > 0)):
        # no split after all: the scan ended early, at a stage whose order had not settled
        # (a 9-DOF chain over 51 201 lines: n0 = 56 there against 36 when scanned on); a
        # scan that ended on its own would only be repeated (a dense grid's sub-band: 1.4 s
        # of a 12.5 s file)
        p, choice = _choose_orders(prepared, s, rank, None, warnings, cap, stages)
    if s.block_rows is not None and choice.block_rows < s.block_rows:
        warnings.append(
            f"block rows {s.block_rows} asked for, but the {p.Hs.shape[0]} lines of"
            f" [{p.band_hz[0]:g}, {p.band_hz[1]:g}] Hz allow a bootstrap replicate at most"
            f" {choice.block_rows}: {choice.block_rows} used")
    if s.max_order is not None and choice.n0 >= choice.limit:
        warnings.append(
            f"the largest model order {s.max_order} (states, two per mode: at most "
            f"{s.max_order // 2} modes) was reached before a model fitted the data "
            f"({order.count_peaks(p.Hs)} resonance peaks in the FRF): raise it, or leave it "
            "automatic")
    a = _analyse(p, s, choice, choice.block_rows, progress)
    tried = [a.ref.q]
    retry = _retry_block_rows(p, choice, a)
    if retry is not None:
        b = _analyse(p, s, choice, retry, within(progress, f"{retry} block rows"))
        tried.append(b.ref.q)
        if summary.confirmed_modes(b.modes) > summary.confirmed_modes(a.modes):
            a = b
    warnings.extend(a.warnings)
    ref, reps, clusters, modes = a.ref, a.reps, a.clusters, a.modes
    fit = _physical_fit(p, modes)
    orders = _orders_info(choice, ref, reps.n_qr, p.T, p.weighting, p.pole_map,
                          "measured" if p.factor is None else "receptance", tried, a.directions)
    if not part:  # a split band's merge says it once for its sub-bands
        warnings.extend(_directions_warning(orders, p.Hs.shape[1]))
        warnings.extend(mode_warnings(modes, p.frequency, p.pole_map.shift))
    return Result(
        modes=modes,
        trashbox_members=int(np.sum(clusters.labels == TRASHBOX)),
        n_clusters=len(clusters.subspaces.groups),
        settings=s.to_dict(),
        warnings=warnings,
        poles=PoleTable.from_poles(reps.poles, clusters.labels, reps.replicate),
        band_hz=(float(p.band_hz[0]), float(p.band_hz[1])),
        orders=orders,
        runtime_s=time.perf_counter() - t0,
        reference_model=ref.model,
        reciprocity=p.reciprocal,
        frf_fit=_frf_fit(p, fit.synthesized),
        frf_fit_error=_oriented(fit.normalised_error, p.reciprocal),
        stabilization=stabilization.stabilization_poles(
            choice.models, p.T, p.band_hz, s.zeta_max, p.pole_map),
        shape_channels=list(p.data.input_names if p.reciprocal else p.data.output_names),
        n_lines=int(p.H.shape[0]),
        noise=None if p.noise is None else NoiseInfo.from_estimate(
            p.noise, list(p.data.output_names), a.dispersion),
    )


@dataclass
class _Analysis:
    """A band's analysis at one number of block rows: the reference model, its dispersion
    against the noise model, the replicates, their clusters, the modes, the warnings the
    replicates gave, and the principal directions of the outputs the replicates identified
    on (``None``: all the outputs)."""

    ref: reference.Reference
    dispersion: float
    reps: replicates.ReplicatePoles
    clusters: reference.Clusters
    modes: list[IdentifiedMode]
    warnings: list[str]
    directions: int | None = None


def _analyse(
    p: Prepared, s: Settings, choice: order.OrderChoice, q: int,
    progress: ProgressCallback | None,
) -> _Analysis:
    """Reference model, bootstrap, clusters, modes and refinement of the prepared band at
    the chosen orders and ``q`` block rows."""
    warnings: list[str] = []
    tell(progress, "reference")
    ref = reference.build_reference(
        p.z, p.Hs, p.scales, p.line_weights, choice.reference, p.T,
        p.band_rad_s, s.zeta_max, s.coalescence, p.pole_map, q,
    )
    dispersion, H_ref, snr2 = 1.0, None, None
    params = whitening.mode_parameters(*p.Hs.shape[1:])
    if p.variance is not None:
        H_ref = ref.modal.frequency_response(p.z)
        dispersion = whitening.dispersion(H_ref, p.Hs, p.variance, choice.reference)
        snr2 = whitening.mode_snr2(ref.modal, p.z, p.variance, jobs=s.jobs) / dispersion
        _check_decaying(p, ref, snr2, params, s.zeta_max)  # before the bootstrap's work
    outputs = None if p.variance is None else whitening.principal_outputs(
        p.Hs, p.variance, choice.reference, ref.q)
    reps = _replicates(p, s, ref, choice.reference, counter(progress, "bootstrap", s.n_bootstrap),
                       warnings, dispersion, H_ref, outputs)
    tell(progress, "summary")
    clusters = reference.cluster_against_reference(ref, reps, s.n_bootstrap, s.threshold)
    modes = summary.summarise_clusters(
        clusters.labels, clusters.rho, reps.poles, reps.shapes, reps.replicate,
        clusters.subspaces, ref.modes, p.scales, ref.contribution, s.n_bootstrap,
        s.min_physicalness, snr2, params, outputs,
    )
    if _refined(p):
        tell(progress, "refinement")
        modes = summary.refine_physical_modes(
            modes, ref.modal.poles, ref.modal.oscillatory, p.omega, p.H, p.noise_variance,
            p.pole_map, s.jobs, s.n_bootstrap)
    return _Analysis(ref=ref, dispersion=dispersion, reps=reps, clusters=clusters,
                     modes=modes, warnings=warnings,
                     directions=None if outputs is None else int(outputs.shape[1]))


def _check_decaying(p: Prepared, ref: reference.Reference, snr2: np.ndarray,
                    params: int, zeta_max: float) -> None:
    """Refuse an FRF whose detected resonances the reference model fits with growing poles.

    Counted (:func:`automodal.core.reference.growing_share`): the modal contributions of
    the modes that the noise would not give by chance
    (:func:`automodal.core.physicalness.familywise_threshold`) and whose damping ratio, of
    either sign, is below ``zeta_max``, as for the physical candidates. The contribution,
    not the SNR^2: the pole-zero pairs of an over-sized model of exact data have an SNR^2
    of rounding. Most of it on growing model poles, with the conjugate FRF fitting their
    decaying images better (:func:`_conjugate_fits_better`), means the FRF is in the other
    sign convention. (Whether a window decay, added back, makes the poles grow is not
    judged: on lightly damped hammer data the estimated decay minus the window's is
    slightly negative by chance.)

    Raises
    ------
    InputError
    """
    detected = snr2 > physicalness.familywise_threshold(params, snr2.size)
    model_poles = p.pole_map.to_model(ref.modes.poles)
    # candidates and their mirror images: |zeta| below the largest damping of a mode
    light = np.abs(pole_damping_ratio(model_poles)) < zeta_max
    weight = np.where(detected & light, ref.contribution, 0.0)
    band = tuple(p.pole_map.model_omega(np.asarray(p.band_rad_s)))  # prewarped as the poles
    share = reference.growing_share(model_poles, weight, band)
    if share > reference.GROWING_SHARE_LIMIT and _conjugate_fits_better(p, model_poles[light]):
        raise InputError(
            f"{share:.0%} of the FRF's detected resonant response fits poles that grow in"
            " time: the FRF uses the other sign convention (e^-iwt, the complex conjugate of"
            " automodal's e^+iwt); store its complex conjugate (docs/frf-file.md)",
            p.data.source)


CONJUGATE_EVIDENCE = 1e-3
""":func:`_conjugate_fits_better`: the false-alarm probability of its F test on noise."""


def _conjugate_fits_better(p: Prepared, poles: np.ndarray) -> bool:
    """Whether the conjugate of the analysed FRF fits the decaying images of the model's
    ``poles`` clearly better than the FRF does
    (:func:`automodal.core.synthesis.conjugate_residual_ratio`): its residual at most half,
    and below the :data:`CONJUGATE_EVIDENCE` quantile of the F distribution that the ratio
    of two equal noise residuals follows. On noise, a model's detected growing poles (one
    white-noise SISO FRF of 1000 lines in three had them) are as often decaying in a
    conjugate's model, and the test passes them."""
    from scipy.special import fdtri

    ratio, dof = synthesis.conjugate_residual_ratio(p.omega, p.H, poles, _power(p.data))
    if dof <= 0:
        return False
    return ratio < min(0.5, float(fdtri(dof, dof, CONJUGATE_EVIDENCE)))


def _refined(p: Prepared) -> bool:
    """Whether the physical modes of ``p`` are refined: with a noise model, on lines whose
    errors are independent (:func:`_independent_lines`)."""
    return p.noise is not None and _independent_lines(p.data)


def _retry_block_rows(p: Prepared, choice: order.OrderChoice, a: _Analysis) -> int | None:
    """Block rows for a second analysis of the band, or ``None``.

    When the refinement could not confirm a physical mode (its pole left its reach, or its
    width changed more than :data:`automodal.core.refine.MAX_DAMPING_CHANGE` times, so the
    mode kept its bootstrap statistics), the reference's pole there is not the data's: the
    subspace estimate of a band of many close modes seen by many outputs is biased at the
    default rows (``docs/method.md`` 1). The band is analysed again at the order scan's
    rows, ``q ny >= 3 n`` (:func:`automodal.core.subspace.scan_block_rows`), as far as a
    replicate's lines allow, and :func:`_identify` keeps the analysis whose refinement
    confirms more physical modes.
    """
    if not _refined(p) or summary.unconfirmed_modes(a.modes) == 0:
        return None
    N, ny, nu = p.Hs.shape
    q = min(subspace.scan_block_rows(choice.reference, ny), order.block_row_budget(N, ny, nu))
    return q if q > a.ref.q else None


def _replicates(
    p: Prepared,
    s: Settings,
    ref: reference.Reference,
    n: int,
    progress: Callable[[int], None] | None,
    warnings: list[str],
    dispersion: float = 1.0,
    H_ref: np.ndarray | None = None,
    outputs: np.ndarray | None = None,
) -> replicates.ReplicatePoles:
    """The bootstrap: record replicates when the data have repeated records (and
    ``s.resample`` allows), noise replicates around the reference model's FRF ``H_ref``
    with the noise model, else frequency-line replicates; all their modes stacked.
    ``outputs``: the output directions the replicates identify on
    (:func:`automodal.core.whitening.principal_outputs`; their shapes come back in every
    output), or None for all the outputs."""
    from automodal.core.noise import mean_as_precise

    rng = np.random.default_rng(s.seed)
    records = replicates.band_records(
        p.data.records, p.data.frequency, p.frequency, p.reciprocal, s.resample, p.data.source
    )
    if records is not None and s.resample == "auto" and p.noise is not None and not (
            mean_as_precise(records, p.noise_variance)):
        # averaging resampled records is not the FRF's estimator (H1 of random force
        # against the mean of ratio records): such replicates are several times noisier
        # than the FRF and lose its weaker modes
        warnings.append(
            f"the {records.shape[0]} repeated records are not resampled: their mean is a"
            " noisier estimate than the FRF (an H1 estimate, not their mean), so the"
            " replicates resample as for data without records")
        records = None
    if records is not None:
        rw = bootstrap.record_weights(records.shape[0], s.n_bootstrap, rng)
        if p.factor is not None:  # in the models' form, as Hs
            records = records / p.factor[None, :, None, None]
        reps = replicates.run_record_replicates(
            ref.basis, records / p.scales[None, None, :, None], n, p.T, rw, p.line_weights,
            s.jobs, progress, outputs,
        )
        warnings.append(
            f"bootstrap over the {records.shape[0]} repeated records (each replicate averages"
            " a resample of them): the spread reflects the records' own noise"
        )
    elif s.resample == "noise" and p.variance is not None and H_ref is not None:
        seeds = rng.integers(0, 2**63 - 1, size=s.n_bootstrap)
        reps = replicates.run_noise_replicates(
            ref.basis, H_ref, p.variance * dispersion, n, p.T, seeds, p.line_weights,
            s.jobs, progress, outputs,
        )
        warnings.append(
            f"bootstrap of the noise model (source: {p.noise.source}): each replicate is the"
            " reference model's FRF plus fresh noise of the estimated variance"
            f" (times {dispersion:.3g}, the reference model's residual over the noise)"
        )
    else:
        if s.resample == "noise":
            warnings.append("resample='noise' needs the noise weighting, which this run did"
                            " not use (output-only data, or no noise model): frequency lines"
                            " resampled instead")
        weights = bootstrap.line_weights(p.H.shape[0], s.n_bootstrap, rng)
        reps = replicates.run_replicates(
            ref.basis, p.Hs, n, p.T, weights * p.line_weights[None, :], s.jobs, progress,
            outputs,
        )
        warnings.append(
            "bootstrap over frequency lines: the spread is conditional on the one noise"
            " realization in the data"
        )
        if not _independent_lines(p.data):
            warnings.append(
                "output-only half spectra without records: their errors are correlated"
                " across lines, so the intervals of this line bootstrap are too narrow"
                " (several times, on simulated tests); give the time records, or convert"
                " them again, so that the bootstrap resamples stretches of the record")
    return replicates.stack_replicates(reps, p.H.shape[1], p.pole_map)


def _principal_warning(directions: Sequence[int], n_outputs: int,
                       n_bands: int | None = None) -> str:
    """The warning that the bootstrap replicates identified on principal directions of the
    outputs (:func:`automodal.core.whitening.principal_outputs`): ``directions``, their
    number in each band analysed on them, of ``n_bands`` sub-bands of a split band (the
    others' replicates used every output)."""
    lo, hi = min(directions), max(directions)
    scope = [] if lo == hi else ["per sub-band"]
    if n_bands is not None and len(directions) < n_bands:
        scope.append(f"in {len(directions)} of the {n_bands} sub-bands")
    scope.append("twice those above the noise")
    count = f"{lo}" if lo == hi else f"{lo}-{hi}"
    return (f"the bootstrap replicates identified on {count} principal directions of the"
            f" {n_outputs} outputs ({', '.join(scope)}): their shapes vary only"
            " within those directions, and mode_shape_std adds the others' share of the noise"
            " as the directions without structure among them show it")


def _orders_info(
    choice: order.OrderChoice, ref: reference.Reference, n_qr: int, T: float,
    weighting: str, pole_map: PoleMap, form: str, tried: list[int],
    directions: int | None = None,
) -> dict[str, object]:
    """``Result.orders``: the scan, the orders chosen and how the models were computed
    (``weighting``: the one that ran, ``"noise"`` or ``"envelope"``; ``form``: the FRF's
    the models fitted, ``"measured"`` or ``"receptance"``; ``window_decay_per_s``
    and ``discrete_sample_rate_hz``: how the model's poles became the structure's, see
    :class:`~automodal.core.pole_map.PoleMap`; ``tried``: the block rows of every analysis
    of the band, in order, see :func:`_retry_block_rows`; ``directions``: the principal
    directions of the outputs the kept analysis's replicates identified on, ``None`` for
    all the outputs)."""
    return {
        "scanned": [int(x) for x in choice.scanned],
        "misfit": [float(x) for x in choice.misfit],
        "n0": int(choice.n0),
        "n0_rule": choice.rule,
        "noise_directions": choice.noise_directions,
        "reference": int(choice.reference),
        "block_rows": int(ref.q),
        "block_rows_tried": [int(q) for q in tried],
        "basis": "monomial" if ref.basis.monomial else "orthonormal",
        "weighting": weighting,
        "form": form,
        "bilinear_T": float(T),
        "replicates_on_qr_path": int(n_qr),
        "replicate_directions": directions,
        "reference_path": ref.model.path,
        "window_decay_per_s": float(pole_map.shift),
        "discrete_sample_rate_hz": pole_map.sample_rate,
    }


def _frf_fit(p: Prepared, H_syn: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(frequency_hz, measured, synthesized)`` in the input's orientation."""
    return (p.frequency, np.ascontiguousarray(_oriented(p.H, p.reciprocal)),
            np.ascontiguousarray(_oriented(H_syn, p.reciprocal)))


def _physical_fit(p: Prepared, modes: list[IdentifiedMode]) -> synthesis.FixedPoleFit:
    """The analysed FRF synthesized from the physical modes' poles, with residues and upper
    and lower residuals fitted by least squares (:mod:`automodal.core.synthesis`).

    The poles are carried back to where they are in the data (the model's poles: an
    exponential window's decay, prewarped sampled spectra). Output-only half spectra have
    the pole-residue form as they are (power 0)."""
    phys = [m for m in modes if m.physical and np.isfinite(m.frequency_hz)
            and np.isfinite(m.damping_ratio)]
    lam = synthesis.modal_poles(np.array([m.frequency_hz for m in phys], dtype=float),
                                np.array([m.damping_ratio for m in phys], dtype=float))
    return synthesis.fit_fixed_poles(p.omega, p.H, p.pole_map.to_model(lam), _power(p.data))


def mode_warnings(
    modes: list[IdentifiedMode], frequency: np.ndarray, window_decay: float = 0.0
) -> list[str]:
    """The run's warnings about its modes, at the analysed lines ``frequency`` (Hz):
    damping the lines do not resolve, poles several modes share, resonances the band's
    edges cut."""
    return (resolution_warnings(modes, frequency, window_decay) + shared_pole_warnings(modes)
            + edge_warnings(modes, frequency, window_decay))


def resolution_warnings(
    modes: list[IdentifiedMode], frequency: np.ndarray, window_decay: float = 0.0
) -> list[str]:
    """One warning per physical mode whose damping the line spacing cannot resolve
    (:func:`automodal.core.summary.resolved`: a half-power bandwidth under about one and
    a half lines, judged at the mode)."""
    f = np.asarray(frequency, dtype=float)
    if f.size < 2:
        return []
    out = []
    for m in sorted((m for m in modes if m.physical), key=lambda m: m.frequency_hz):
        if not (np.isfinite(m.frequency_hz) and np.isfinite(m.damping_ratio)):
            continue
        if not resolved(m.frequency_hz, m.damping_ratio, f, window_decay):
            df = local_spacing(f, m.frequency_hz)
            out.append(
                f"the mode at {m.frequency_hz:.4g} Hz: its half-power bandwidth"
                f" (2 zeta f = {2 * m.damping_ratio * m.frequency_hz:.3g} Hz) is below"
                f" {RESOLUTION_DECAY / np.pi:.2f} line spacings ({df:.3g} Hz): the damping"
                " is not resolved by the frequency lines (the response outlasts the record);"
                " treat its damping as an estimate of the order of the resolution only"
            )
    return out


def edge_warnings(
    modes: list[IdentifiedMode], frequency: np.ndarray, window_decay: float = 0.0
) -> list[str]:
    """One warning per physical mode whose resonance in the data reaches past the first or
    the last analysed line: the band cuts it, and its estimate, its shape above all, rests
    on part of it (on the fresh family seeds 1151 f_01 and f_07, modes reported 0.022 and
    0.026 Hz inside the last line, their half-power bands reaching past it, had shapes of
    MAC 0.32 and 0.71 against the truth).

    The resonance's half-width in the data is ``zeta f`` plus ``window_decay / (2 pi)``
    (an exponential window's decay rate, 1/s, widens every peak by it; the reported damping
    has it taken out). A mode reported wholly outside the lines is said to be so."""
    f = np.asarray(frequency, dtype=float)
    if f.size < 2:
        return []
    out = []
    for m in sorted((m for m in modes if m.physical), key=lambda m: m.frequency_hz):
        fm = m.frequency_hz
        half = abs(m.damping_ratio) * fm + window_decay / (2.0 * np.pi)
        if not (np.isfinite(fm) and np.isfinite(half)):
            continue
        cut = [f"the {name} analysed line ({edge:.4g} Hz)" for name, edge, past in (
            ("first", f[0], fm - half < f[0]), ("last", f[-1], fm + half > f[-1])) if past]
        if not cut:
            continue
        if f[0] <= fm <= f[-1]:
            where = "reaches past " + " and ".join(cut)
        else:
            where = f"lies outside the analysed lines [{f[0]:.4g}, {f[-1]:.4g}] Hz"
        out.append(f"the mode at {fm:.4g} Hz: its resonance [{fm - half:.4g}, {fm + half:.4g}] Hz"
                   f" (half-power band) {where}, so its estimate rests on part of it (its shape"
                   " above all); analyse a wider band, or measure beyond it")
    return out


def shared_pole_warnings(modes: list[IdentifiedMode]) -> list[str]:
    """One warning per pole that several physical modes share (a repeated pair refined as
    one pole, ``docs/method.md`` 6): their frequency, damping and intervals are the pole's,
    which hold the pair's middle rather than each mode."""
    poles = Counter((m.frequency_hz, m.damping_ratio) for m in modes
                    if m.physical and m.estimator == "ml")
    return [f"{count} physical modes at {f:.6g} Hz share one pole (a repeated pair: one"
            " pole's residue holds two modes' shapes): their frequency, damping and"
            " intervals are the pole's, which hold the pair's middle rather than each mode"
            for (f, _), count in sorted(poles.items()) if count > 1]
