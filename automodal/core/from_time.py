"""From time series to FRFs: the automatic choices that turn a :class:`TimeSeries` into an
:class:`FRFData` for the pipeline (pure: no I/O, nothing printed).

Three routes, chosen from the data:

* **random excitation** (forces measured, not impulsive): Welch H1 with a Hann window and
  50 % overlap, segment from :func:`~automodal.core.spectra.choose_segment`, with coherence
  and record estimates;
* **impact** (forces impulsive): one rectangular record per hammer hit
  (:func:`~automodal.core.spectra.detect_hits`), force window, an exponential window only
  when the response has not died out in the record, H1 over the hits (each hit a record);
* **operational** (no forces): half spectra of all outputs against automatic reference
  channels (:func:`~automodal.core.spectra.choose_references`), the references acting as
  the inputs; ``attributes["analysis"] = "operational"``.

Only lines ``0 < f <= usable_fraction * fs / 2`` are kept: the 0 Hz line (means removed)
is dropped, and by default so is the top of the band where an acquisition system's
anti-alias filter acts (analysers show ``fs / 2.56`` for that reason).

:func:`as_frfdata` is the pipeline's input stage: what a reader gave (FRFs, or time series)
as FRFs. :mod:`automodal.core.spectra` (and scipy.signal with it) is imported only when
time series are analysed, so that importing this module stays cheap.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from automodal.errors import InputError
from automodal.frfdata import FRFData, quantity_problem
from automodal.timedata import TimeSeries

__all__ = [
    "EXCITATIONS", "RECORDS_BYTES", "USABLE_FRACTION", "as_frfdata", "frfdata_from_time",
    "operational_records",
]

EXCITATIONS = ("auto", "random", "impact", "operational")
"""Routes of :func:`frfdata_from_time`; ``"auto"`` picks one from the data."""

USABLE_FRACTION = 1.0 / 1.28
"""Fraction of the Nyquist band kept (``fs / 2.56``; above it anti-alias filters act)."""

DEFAULT_QUANTITY = "displacement"
"""Quantity assumed when the data do not say (the FRF file's default)."""


def as_frfdata(data: FRFData | TimeSeries, **options: Any) -> FRFData:
    """The test as FRFs: ``data`` itself, or the FRFs made from its time series.

    Parameters
    ----------
    data : FRFData or TimeSeries
        What a reader gave (:func:`automodal.io.readers.read_any`) or Python code made.
    **options
        Keyword arguments of :func:`frfdata_from_time` (time series only).

    Returns
    -------
    FRFData
        ``data`` unchanged when it is one. For a :class:`TimeSeries`, the FRFs of
        :func:`frfdata_from_time` with its choices (segment length, references, windows)
        in ``attributes["time_analysis"]``, so that the report shows them, the decay rate
        of its window (1/s, 0 without one) in ``attributes["window_decay_per_s"]``, so that
        the pipeline takes it out of the damping, and the series' ``source`` (which
        :func:`frfdata_from_time` keeps).

    Raises
    ------
    InputError
        When the time series cannot be analysed (a dead channel, a record too short, an
        unknown quantity, ...): one line naming the series' source.
    TypeError
        If ``data`` is neither an :class:`FRFData` nor a :class:`TimeSeries`.
    """
    if isinstance(data, FRFData):
        return data
    if not isinstance(data, TimeSeries):
        raise TypeError(f"expected FRFData or TimeSeries, not {type(data).__name__}")
    try:
        frf, info = frfdata_from_time(data, **options)
    except ValueError as exc:
        raise InputError(str(exc), data.source) from None
    decay = info.get("lag_window_decay_per_s") or info.get("exponential_decay_per_s") or 0.0
    frf.attributes["time_analysis"] = info
    frf.attributes["window_decay_per_s"] = float(decay)
    if info["analysis"] == "operational":  # half spectra: rational in exp(j w / fs)
        frf.attributes["discrete_sample_rate_hz"] = float(info["analysed_sample_rate_hz"])
    return frf


def frfdata_from_time(
    ts: TimeSeries,
    *,
    excitation: str = "auto",
    nperseg: int | None = None,
    references: list[int] | None = None,
    max_references: int = 3,
    lag_tail: float | None = None,
    usable_fraction: float = USABLE_FRACTION,
    decimation: int = 1,
) -> tuple[FRFData, dict[str, Any]]:
    """Turn a time-series test into FRFs (H1 or half spectra) for the pipeline.

    Parameters
    ----------
    ts : TimeSeries
        The test. ``ts.attributes["quantity"]``, when present, is the response quantity
        (one of ``displacement``, ``velocity``, ``acceleration``).
    excitation : {"auto", "random", "impact", "operational"}
        ``"auto"``: operational without inputs, impact when the forces are impulsive
        (:func:`~automodal.core.spectra.detect_hits`), random otherwise.
        ``"operational"`` with measured forces ignores them.
    nperseg : int, optional
        Segment length (random: Welch segment; operational: the number of lags, which
        is also the FFT length). Default :func:`~automodal.core.spectra.choose_segment`. Ignored
        for impacts (one record per hit).
    references : list of int, optional
        Reference outputs of the operational route (default automatic).
    max_references : int
        Most automatic references.
    lag_tail : float, optional
        Value of the exponential lag window at the max lag (operational route; default
        :data:`automodal.core.spectra.LAG_WINDOW_TAIL`).
    usable_fraction : float
        Fraction of the Nyquist band kept, in (0, 1].
    decimation : int
        Operational route only: the records are decimated by this factor first
        (:func:`~automodal.core.spectra.decimate`), and the lines, the usable band and
        ``nperseg`` are those of the decimated records (the pipeline chooses it from a first
        pass, :mod:`automodal.core.ambient_plan`).

    Returns
    -------
    data : FRFData
        ``quantity`` from the attributes, else ``"displacement"`` (the FRF file's default;
        ``info["quantity_assumed"]`` says so). H1 routes set ``coherence``, ``records``
        and ``attributes["analysis"] = "h1"``; the operational route has the references
        as inputs (named after them) and ``attributes["analysis"] = "operational"``.
        Other attributes of ``ts`` are copied; ``source`` is kept.
    info : dict
        The choices, JSON-friendly: ``analysis``, ``sample_rate_hz``, ``n_samples``,
        ``nperseg``, ``window``, ``n_segments``, ``frequency_resolution_hz``, ``band_hz``,
        ``n_lines``, ``quantity``, ``quantity_assumed`` (``n_segments`` counts Welch
        segments, hits, or for the operational route the independent blocks of one max lag,
        ``n_samples // max_lag``) and per route: ``overlap``,
        ``n_records``, ``segments_per_record`` (H1); ``hits``, ``force_window_samples``,
        ``exponential_decay_per_s`` (impact); ``references``, ``reference_names``,
        ``max_lag_samples``, ``max_lag_s``, ``lag_window``, ``lag_window_tail``,
        ``lag_window_decay_per_s``, ``decimation``, ``analysed_sample_rate_hz``,
        ``n_records`` (operational: the half spectra's records,
        :func:`operational_records`; 0 when none). A window decay ``a`` > 0 adds ``a`` to
        every pole's decay rate. :func:`as_frfdata` records it (and, for half spectra, the
        sample rate) in the attributes, from which the pipeline maps the poles back
        (:class:`~automodal.core.pole_map.PoleMap`); FRFs identified from this function's
        result alone need :func:`~automodal.core.spectra.undo_exponential_window`.

    Raises
    ------
    ValueError
        On an unknown ``excitation`` or ``quantity``, impact or random analysis without
        inputs, a constant (dead) channel, or a record too short for the analysis.
    """
    from automodal.core import spectra

    if lag_tail is None:
        lag_tail = spectra.LAG_WINDOW_TAIL
    if excitation not in EXCITATIONS:
        raise ValueError(f"excitation must be one of {EXCITATIONS}, got {excitation!r}")
    if not 0.0 < usable_fraction <= 1.0:
        raise ValueError("usable_fraction must be in (0, 1]")
    if int(decimation) != decimation or decimation < 1:
        raise ValueError(f"decimation must be an integer >= 1, got {decimation!r}")
    _check_not_constant(ts.outputs, ts.output_names, "output")
    if ts.inputs is not None:
        _check_not_constant(ts.inputs, ts.input_names, "input")
    attributes = dict(ts.attributes)
    quantity = attributes.pop("quantity", None)
    assumed = quantity is None
    quantity = DEFAULT_QUANTITY if assumed else str(quantity)
    problem = quantity_problem(quantity)
    if problem:
        raise ValueError(problem)

    hits, swapped = None, None
    if excitation == "auto":
        if ts.inputs is None:
            excitation = "operational"
        else:
            hits = spectra.detect_hits(ts.inputs, ts.sample_rate)
            excitation = "random" if hits is None else "impact"
            if hits is None:
                swapped = _forces_look_swapped(ts)
    elif excitation in ("random", "impact") and ts.inputs is None:
        raise ValueError(f"{excitation} analysis needs measured forces (inputs)")
    if decimation != 1 and excitation != "operational":
        raise ValueError("decimation applies to the operational (output-only) route only")

    fs = ts.sample_rate
    info: dict[str, Any] = {
        "sample_rate_hz": fs,
        "n_samples": ts.n_samples,
        "duration_s": ts.duration,
        "quantity": quantity,
        "quantity_assumed": assumed,
        "usable_fraction": float(usable_fraction),
    }
    if excitation == "operational":
        freq, H, coherence, records, input_names = _operational(
            ts, nperseg, references, max_references, lag_tail, int(decimation),
            usable_fraction, info,
        )
        fs = info["analysed_sample_rate_hz"]
        attributes["analysis"] = "operational"
    elif excitation == "impact":
        freq, H, coherence, records = _impact(ts, hits, info)
        input_names = ts.input_names
        attributes["analysis"] = "h1"
    else:
        freq, H, coherence, records = _random(ts, nperseg, info)
        input_names = ts.input_names
        attributes["analysis"] = "h1"
        if swapped:
            info["warnings"] = [*info.get("warnings", []), swapped]

    top = usable_fraction * fs / 2.0
    if "force_limit_hz" in info:  # impacts: only where the hammer excites the structure
        top = min(top, info["force_limit_hz"])
    keep = (freq > 0) & (freq <= top * (1 + 1e-12))
    if np.count_nonzero(keep) < 2:
        raise ValueError("the record is too short: fewer than 2 frequency lines")
    lines = np.flatnonzero(keep)
    keep = slice(int(lines[0]), int(lines[-1]) + 1)  # contiguous: views, not copies
    info["band_hz"] = [float(freq[keep][0]), float(freq[keep][-1])]
    info["n_lines"] = int(lines.size)
    data = FRFData(
        frequency=freq[keep],
        frf=H[keep],
        quantity=quantity,
        coherence=None if coherence is None else coherence[keep],
        records=None if records is None else records[:, keep],
        output_names=list(ts.output_names),
        input_names=list(input_names),
        attributes=attributes,
        source=ts.source,
    )
    return data, info


def _random(
    ts: TimeSeries, nperseg: int | None, info: dict[str, Any]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Welch H1 (Hann, 50 % overlap)."""
    from automodal.core import spectra

    fs = ts.sample_rate
    L = int(nperseg or spectra.choose_segment(ts.n_samples, fs))
    n_seg = spectra.segment_count(ts.n_samples, L, spectra.DEFAULT_OVERLAP)
    if n_seg < 1:
        raise ValueError(f"the record ({ts.n_samples} samples) is shorter than one segment ({L})")
    freq, H, coh, rec = spectra.h1_estimate(ts.outputs, ts.inputs, fs, L, "hann")
    info.update(
        analysis="h1",
        excitation="random",
        window="hann",
        nperseg=L,
        overlap=spectra.DEFAULT_OVERLAP,
        n_segments=int(n_seg),
        frequency_resolution_hz=fs / L,
        n_records=int(rec.shape[0]),
        segments_per_record=int(n_seg // rec.shape[0]),
    )
    return freq, H, coh, rec


def _impact(
    ts: TimeSeries, hits: tuple[np.ndarray, int] | None, info: dict[str, Any]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """H1 over hammer hits: rectangular records, force window, exponential if needed."""
    from automodal.core import spectra

    fs = ts.sample_rate
    if hits is None:
        hits = spectra.detect_hits(ts.inputs, fs)
        if hits is None:
            raise ValueError("the forces are not impulsive: no hammer hit found")
    starts, length = hits
    if length < 32:
        raise ValueError(f"the records after the hits are too short ({length} samples)")
    keep, dropped = spectra.screen_hits(ts.inputs, ts.outputs, starts, length)
    if not keep.any():
        raise ValueError(f"every hammer hit is unusable ({'; '.join(dropped)}): measure again")
    starts = starts[keep]
    u, kept = spectra.force_window(ts.inputs, starts, length)
    force_limit = spectra.force_band_limit(u, starts, length, fs)
    decay = spectra.decay_needed(ts.outputs, starts, length, fs)
    u = spectra.exponential_records(u, starts, length, fs, decay)
    y = spectra.exponential_records(ts.outputs, starts, length, fs, decay)
    freq, H, coh, rec = spectra.h1_estimate(
        y, u, fs, length, "boxcar", starts=starts, segments_per_record=1
    )
    info.update(
        analysis="h1",
        excitation="impact",
        window="boxcar" + (" + exponential" if decay > 0 else "") + " + force window",
        nperseg=int(length),
        n_segments=int(starts.size),
        frequency_resolution_hz=fs / length,
        hits=[int(s) for s in starts],
        force_window_samples=int(kept),
        exponential_decay_per_s=float(decay),
        force_limit_hz=force_limit,
        dropped_hits=len(dropped),
        warnings=dropped,
        force_drop_db=spectra.FORCE_DROP_DB,
        n_records=int(rec.shape[0]),
        segments_per_record=1,
    )
    return freq, H, coh, rec


RECORDS_BYTES = 1 << 27
"""Most memory (128 MB) the records of output-only half spectra take: fewer records on a
very large test (64 outputs, 3 references and 16384 lags leave 6 over the usable band), 48
on common ones (20 outputs, 3 references and 4096 lags take 70 MB over the usable band).
The identification holds a few copies of them at its peak (about 2.7 times, measured)."""


def operational_records(
    n_samples: int, max_lag: int, n_outputs: int, n_refs: int, n_lines: int | None = None
) -> int:
    """How many records the half spectra keep (0: none).

    One per stretch of the record, as many as the plan's independent stretches
    (:data:`automodal.core.ambient_plan.MIN_BLOCKS`, 48), each at least ``max_lag``
    samples long, within :data:`RECORDS_BYTES`. Their spread is the half spectra's error
    (:func:`automodal.core.spectra.half_spectrum_records`): the noise model and the
    bootstrap's replicates come from them. Fewer than 2 would say nothing: none then.
    ``n_lines``: the lines each record keeps (default all ``max_lag // 2 + 1``).
    """
    from automodal.core import ambient_plan

    lines = max_lag // 2 + 1 if n_lines is None else int(n_lines)
    per_record = lines * n_outputs * n_refs * 16
    n = min(ambient_plan.MIN_BLOCKS, n_samples // max_lag, RECORDS_BYTES // per_record)
    return n if n >= 2 else 0


def _operational(
    ts: TimeSeries,
    nperseg: int | None,
    references: list[int] | None,
    max_references: int,
    tail: float,
    decimation: int,
    usable_fraction: float,
    info: dict[str, Any],
) -> tuple[np.ndarray, np.ndarray, None, np.ndarray | None, list[str]]:
    """Half spectra of all outputs (decimated first when asked) against (automatic)
    references."""
    from automodal.core import spectra

    y = ts.outputs if decimation == 1 else spectra.decimate(ts.outputs, decimation)
    fs = ts.sample_rate / decimation
    n = y.shape[0]
    L = int(nperseg or spectra.choose_segment(n, fs))
    if not 1 <= L < n:
        raise ValueError(f"the record ({n} samples) is shorter than the max lag ({L})")
    refs = (
        list(references)
        if references is not None
        else spectra.choose_references(y, fs, max_refs=max_references)
    )
    # the lines up to the usable band's top are all frfdata_from_time keeps
    n_lines = min(L // 2, math.floor(usable_fraction * L / 2 * (1 + 1e-12))) + 1
    n_rec = operational_records(n, L, y.shape[1], len(refs), n_lines)
    if n_rec >= 2:
        freq, records = spectra.half_spectrum_records(y, refs, fs, L, n_rec, tail=tail,
                                                      n_lines=n_lines)
        G = records.mean(axis=0)
    else:
        freq, G = spectra.half_spectra(y, refs, fs, L, tail=tail)
        records = None
    m = L
    names = [ts.output_names[i] for i in refs]
    info.update(
        analysis="operational",
        excitation="operational",
        window="exponential lag window",
        nperseg=L,
        decimation=int(decimation),
        analysed_sample_rate_hz=float(fs),
        n_segments=int(n // m),
        frequency_resolution_hz=fs / L,
        references=[int(i) for i in refs],
        reference_names=names,
        max_lag_samples=int(m),
        max_lag_s=m / fs,
        lag_window="exponential",
        lag_window_tail=float(tail),
        lag_window_decay_per_s=spectra.exponential_decay(m, fs, tail),
        n_records=0 if records is None else int(records.shape[0]),
    )
    return freq, G, None, records, names


def _forces_look_swapped(ts: TimeSeries) -> str | None:
    """A warning when the forces are not impulsive but a response channel is: a hammer's
    pulses in a response and a ringing force channel mean the channels were given the wrong
    way round (``--forces 1`` for the first column, say), which the random route analyses
    into no mode at all. Only a warning: a spike, an overload or a shock in a response of a
    true random test looks the same to the hit detector."""
    from automodal.core import spectra

    for j, name in enumerate(ts.output_names):
        if spectra.detect_hits(ts.outputs[:, [j]], ts.sample_rate) is not None:
            forces = ", ".join(repr(n) for n in ts.input_names)
            return (f"response channel {name!r} is impulsive (hammer hits, or spikes) while "
                    f"the force channel(s) {forces} are not: analysed as random excitation; "
                    "if the channels are swapped, give the hammer's channel as the force "
                    "(--forces takes names or 0-based positions)")
    return None


def _check_not_constant(x: np.ndarray, names: list[str], side: str) -> None:
    """Refuse a dead (constant) channel: it has no spectrum to analyse."""
    dead = np.flatnonzero(np.ptp(x, axis=0) == 0)
    if dead.size:
        raise ValueError(
            f"{side} channel(s) {', '.join(names[i] for i in dead)} are constant (dead)"
        )
