"""Sanity checks of FRF data before the identification (pure: arrays in, arrays out).

:func:`prepare` is the one entry point: :func:`automodal.pipeline.identify` calls it right
after choosing the band. It refuses what the identification cannot handle with an
:class:`~automodal.errors.InputError` (one line, exit status 2 on the command line), cleans
what can be cleaned (a copy; the caller's data are never changed) and says what it did in
the run's warnings, which go into the report:

========================================  ==================================================
data                                      what happens
========================================  ==================================================
non-finite values, lines not strictly     refused (by FRFData's own rules, checked again
increasing (API callers)                  here: arrays may be changed in place)
more than :data:`MAX_LINES` lines         decimated to at most that many (a warning)
magnitudes above :data:`MAX_MAGNITUDE`    refused (sums of their squares overflow)
an output or input that is zero           dropped (a warning); refused if nothing is left
(below :data:`MIN_MAGNITUDE`)
a line where every FRF is zero            dropped (a warning): a placeholder, not a
                                          measurement
a line more than :data:`OUTLIER_DECADES`  dropped (a warning): a spike or a drop-out, not a
decades off its neighbours                resonance
outputs (or inputs) identical up to a     all but the first of each set dropped (a warning):
factor                                    identical outputs make the data rank-deficient
a magnitude trend over more than          a warning; over :data:`MAX_TREND_DECADES`,
:data:`WARN_TREND_DECADES` decades        refused (the line weights lose all precision)
no resonance peak in the band             a warning: expect no physical mode
a resonance peak on the band's edge       a warning: its mode may be missed (the pipeline
                                          keeps only modes inside the band)
========================================  ==================================================

Not here, because the pipeline does it already: the 0 Hz line is left out by
:func:`automodal.pipeline.select_band` (with a warning), and too few lines for the asked
model order are refused by :func:`automodal.pipeline.identify` (saying how many are needed).
Unevenly spaced lines need nothing: the identification works on any set of lines.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from automodal.core import subspace
from automodal.core.filters import running_max, running_median, running_min
from automodal.core.line_compression import is_uniform
from automodal.core.magnitude import mean_log_magnitude
from automodal.errors import InputError
from automodal.frfdata import FRFData

__all__ = [
    "DUPLICATE_TOLERANCE",
    "MAX_LINES",
    "MAX_MAGNITUDE",
    "MAX_TREND_DECADES",
    "MAX_TOP_FREQUENCY_HZ",
    "MIN_MAGNITUDE",
    "MIN_TOP_FREQUENCY_HZ",
    "OUTLIER_DECADES",
    "WARN_TREND_DECADES",
    "decimate",
    "duplicate_channels",
    "edge_peaks",
    "has_resonance",
    "identified_form",
    "outlier_lines",
    "prepare",
    "trend_decades",
    "zero_channels",
]

MAX_LINES = 200_000
"""Most frequency lines the identification uses; more are decimated (:func:`decimate`:
every k-th line of evenly spaced lines, which a compression then needs, else evenly spread
lines, the band's first and last included). Time and memory grow with the lines: 200 000
lines of a 6-output test took 11 s and 0.8 GB with 100 replicates, and a 10^6-line file
15 s and 0.76 GB through the command line. At that density a mode at a tenth of the band's
top frequency or above keeps 3 lines in its half-power band down to a damping ratio of
7.5e-5."""

MAX_MAGNITUDE = 1e100
"""Largest FRF magnitude accepted: the identification sums squares of the data (over up to
2^26 values), which must stay far from the overflow at 1.8e308. No unit system puts a
measured FRF near this; rescaling the units brings such data into range."""

MIN_TOP_FREQUENCY_HZ = 1e-6
"""Lowest top line of a band accepted (a period of 11 days): below it the frequencies are
not in Hz."""

MAX_TOP_FREQUENCY_HZ = 1e12
"""Highest top line of a band accepted (1 THz): above it the frequencies are not in Hz."""

MIN_MAGNITUDE = 1e-100
"""A channel (or a line) whose largest magnitude is below this, or zero, carries no
information: it is dropped as dead. Squares of such values are near the underflow."""

DUPLICATE_TOLERANCE = 1e-9
"""Two channels are duplicates when ``1 - |<a, b>| / (|a| |b|)`` is below this, i.e. when
they are equal up to a complex factor to within rounding (a relative difference of about
4e-5 or less)."""

WARN_TREND_DECADES = 6.0
"""A trend of the FRF magnitude (running median over the band) spanning more decades than
this gets a warning: the line weights that level it span twice as many."""

MAX_TREND_DECADES = 8.5
"""Above this many decades the line weights span more than about 1e17, beyond the precision
of double arithmetic, and the identification fails; such data are refused with the advice
to narrow the band. Measured on a 4-DOF chain multiplied by 10^(-6 ... -11) across the band
(trends of 4.5 to 9.2 decades): with 1 % noise every mode was found up to 8.2 decades,
noise-free data gave no mode from 7.3 decades on, and at 9.2 the factorisation of the
weighted data failed. An accelerance on lines from 1 mHz to 37 Hz (8.2 decades) was
identified. The trend checked is that of the form identified (:func:`identified_form`): that
accelerance is now identified as a receptance, whose trend is small."""

OUTLIER_DECADES = 8.0
"""A line whose magnitude is more than this many decades above or below the running median
of its neighbours (10 % of the lines) is an outlier. A resonance rises above its
surroundings by about ``1 / (2 zeta)``: 3.7 decades for a damping ratio of 1e-4."""

_SCREEN_LINES = 4096
"""Lines used to screen for duplicate channels (candidates are confirmed on all lines)."""

_MIN_VALUES_FOR_DUPLICATES = 8
"""Fewer values per channel say nothing about duplicates (any two channels of one value
are proportional); such data are too short to identify anyway."""


def prepare(
    data: FRFData, freq: np.ndarray, H: np.ndarray, warnings: list[str], power: int = 0
) -> tuple[FRFData, np.ndarray, np.ndarray, bool]:
    """Check and clean the analysed band of a test before the identification.

    Parameters
    ----------
    data : FRFData
        The whole test (not changed).
    freq : ndarray, shape (N,)
        The band's lines in Hz (> 0), as :func:`automodal.pipeline.select_band` gives them.
    H : ndarray, shape (N, ny, nu)
        The band's FRFs.
    warnings : list of str
        Receives one line per change made or problem seen.
    power : int
        The FRFs are a receptance times ``(j w)^power`` (0 receptance, 1 mobility,
        2 accelerance): the trend checked is that of the form the identification fits
        (:func:`identified_form`).

    Returns
    -------
    data : FRFData
        ``data`` itself, or a copy without the channels that were dropped (FRFs, records,
        coherence, names, nodes, directions and coordinates alike).
    freq : ndarray, shape (M,)
        The lines to analyse (``M <= MAX_LINES``).
    H : ndarray, shape (M, ny', nu')
        Their FRFs, without the dropped channels.
    receptance : bool
        Whether their receptance form is the flatter (:func:`identified_form`), the trend
        checked.

    Raises
    ------
    InputError
        One line naming the test: non-finite values or lines not strictly increasing;
        magnitudes above :data:`MAX_MAGNITUDE`; no channel that is not zero; a magnitude
        trend of more than :data:`MAX_TREND_DECADES` decades.
    """
    source = data.source
    data.validate()  # FRFData's own rules: arrays changed in place since it was made
    freq = np.asarray(freq, dtype=float)
    H = np.asarray(H, dtype=complex)
    freq, H = decimate(freq, H, MAX_LINES, warnings)
    _check_frequency_scale(freq, source)
    _check_magnitude(H, "FRF", source)
    if data.records is not None:
        _check_magnitude(data.records, "repeated records' FRF", source)
    keep_out, keep_in = _usable_channels(data, H, warnings)
    if not (np.all(keep_out) and np.all(keep_in)):
        H = H[:, keep_out][:, :, keep_in]
        data = _select_channels(data, keep_out, keep_in)
    freq, H = _drop_zero_lines(freq, H, warnings)
    freq, H = _drop_outlier_lines(freq, H, warnings)
    if freq.size == 0:
        raise InputError("no usable frequency line in the band", source)
    receptance, decades = identified_form(freq, H, power)
    _check_trend(decades, source, warnings)
    if not has_resonance(H):
        warnings.append(f"no resonance peak in the band [{freq[0]:g}, {freq[-1]:g}] Hz (the FRF "
                        "magnitude has no local maximum that stands out of the noise): expect "
                        "no physical mode")
    for edge in edge_peaks(H):
        f_edge = freq[0] if edge == "low" else freq[-1]
        warnings.append(f"the band's {edge} edge ({f_edge:g} Hz) is on a resonance peak: a "
                        "mode there may be missed or poorly estimated; widen the band")
    return data, freq, H, receptance


def _check_frequency_scale(freq: np.ndarray, source: str | None) -> None:
    """Refuse a band whose top line lies outside [:data:`MIN_TOP_FREQUENCY_HZ`,
    :data:`MAX_TOP_FREQUENCY_HZ`]: frequencies not in Hz (the bilinear map's scale, the
    inverse of the band's frequencies, overflows beyond them: lines scaled by 1e200 or
    1e-200 ended in a failed SVD)."""
    top = float(freq[-1]) if freq.size else 0.0
    if not MIN_TOP_FREQUENCY_HZ <= top <= MAX_TOP_FREQUENCY_HZ:
        raise InputError(f"the band's top line is at {top:.3g} Hz, outside the"
                         f" [{MIN_TOP_FREQUENCY_HZ:g}, {MAX_TOP_FREQUENCY_HZ:g}] Hz of"
                         " vibration tests: give the frequencies in Hz", source)


def _check_magnitude(H: np.ndarray, what: str, source: str | None) -> None:
    """Refuse magnitudes above :data:`MAX_MAGNITUDE` (finite values are an FRFData rule)."""
    with np.errstate(over="ignore"):  # |1e308 + 1e308j| is inf: above the limit indeed
        peak = float(np.max(np.abs(H), initial=0.0))
    if peak > MAX_MAGNITUDE:
        raise InputError(f"{what} magnitudes reach {peak:.3g}, more than the {MAX_MAGNITUDE:g} "
                         "the identification accepts (its sums of squares must not overflow): "
                         "rescale the data (other units)", source)


def decimate(
    freq: np.ndarray, H: np.ndarray, max_lines: int, warnings: list[str]
) -> tuple[np.ndarray, np.ndarray]:
    """Keep at most ``max_lines`` evenly spread lines: every k-th line (the first among
    them) of evenly spaced lines, else the first, the last and lines evenly spread between.

    Parameters
    ----------
    freq : ndarray, shape (N,)
    H : ndarray, shape (N, ny, nu)
    max_lines : int
        Most lines kept (at least 2).
    warnings : list of str
        Receives a line when lines were dropped.

    Returns
    -------
    freq, H
        The same arrays when ``N <= max_lines``, else copies of the kept lines.
    """
    n = freq.size
    if n <= max_lines:
        return freq, H
    if is_uniform(freq):  # every k-th line: still evenly spaced, as a compression needs
        keep = np.arange(0, n, -(-n // max_lines))
    else:
        keep = np.unique(np.round(np.linspace(0, n - 1, max_lines)).astype(np.int64))
    warnings.append(f"the band has {n} frequency lines, more than the {max_lines} the "
                    f"identification uses: decimated to {keep.size} evenly spread lines "
                    f"(about one in {n / keep.size:.3g})")
    return freq[keep], H[keep]


def _drop_zero_lines(
    freq: np.ndarray, H: np.ndarray, warnings: list[str]
) -> tuple[np.ndarray, np.ndarray]:
    """Leave out the lines where every FRF is zero (below :data:`MIN_MAGNITUDE`)."""
    zero = np.max(np.abs(H), axis=(1, 2)) < MIN_MAGNITUDE
    if not zero.any():
        return freq, H
    shown = ", ".join(f"{f:g}" for f in freq[zero][:5]) + (", ..." if zero.sum() > 5 else "")
    warnings.append(f"{int(zero.sum())} line(s) where every FRF is zero ({shown} Hz) were left "
                    "out: placeholders, not measurements")
    return freq[~zero], H[~zero]


def outlier_lines(H: np.ndarray) -> np.ndarray:
    """Which lines are more than :data:`OUTLIER_DECADES` decades off their neighbours.

    The line's magnitude is the largest over channels, each output scaled by its median
    magnitude (a robust scale: one spike does not change it); its neighbours' level is the
    running median of the log magnitude over 10 % of the lines (at least 5).

    Returns
    -------
    ndarray of bool, shape (N,)
    """
    n = H.shape[0]
    if n < 5:
        return np.zeros(n, dtype=bool)
    magnitude = np.abs(H)
    level = np.median(magnitude, axis=(0, 2))
    level = np.where(level > 0, level, np.max(magnitude, axis=(0, 2)))
    with np.errstate(over="ignore"):  # inf: an outlier indeed
        mag = np.max(magnitude / level[None, :, None], axis=(1, 2))
    log_mag = np.log10(np.maximum(mag, np.finfo(float).tiny))
    local = running_median(log_mag, max(5, int(round(0.1 * n)) | 1), mode="mirror")
    return np.abs(log_mag - local) > OUTLIER_DECADES


def _drop_outlier_lines(
    freq: np.ndarray, H: np.ndarray, warnings: list[str]
) -> tuple[np.ndarray, np.ndarray]:
    """Leave out the lines that :func:`outlier_lines` finds."""
    bad = outlier_lines(H)
    if not bad.any():
        return freq, H
    shown = ", ".join(f"{f:g}" for f in freq[bad][:5]) + (", ..." if bad.sum() > 5 else "")
    warnings.append(f"{int(bad.sum())} line(s) more than {OUTLIER_DECADES:g} decades above or "
                    f"below their neighbours ({shown} Hz) were left out: spikes or drop-outs, "
                    "not resonances")
    return freq[~bad], H[~bad]


def zero_channels(H: np.ndarray, axis: int) -> np.ndarray:
    """Which outputs (``axis=1``) or inputs (``axis=2``) are zero: largest magnitude below
    :data:`MIN_MAGNITUDE`.

    Returns
    -------
    ndarray of bool
        One entry per channel.
    """
    other = tuple(a for a in range(3) if a != axis)
    return np.max(np.abs(H), axis=other) < MIN_MAGNITUDE


def duplicate_channels(H: np.ndarray, axis: int) -> dict[int, int]:
    """Channels equal to an earlier one up to a complex factor (see
    :data:`DUPLICATE_TOLERANCE`).

    Parameters
    ----------
    H : ndarray, shape (N, ny, nu)
        FRFs without zero channels.
    axis : {1, 2}
        Outputs (1) or inputs (2).

    Returns
    -------
    dict
        Duplicate channel index -> the first channel it duplicates.

    Notes
    -----
    Each line is scaled to unit norm first (over all channels), so that one outlying line
    cannot make all channels look alike; the scaling keeps exact duplicates exact.
    """
    H = H / np.max(np.abs(H))
    line_norm = np.linalg.norm(H.reshape(H.shape[0], -1), axis=1)
    H = H / np.where(line_norm > 0, line_norm, 1.0)[:, None, None]  # each line counts alike
    X = np.moveaxis(H, axis, 0).reshape(H.shape[axis], -1)
    n = X.shape[0]
    if n < 2 or X.shape[1] < _MIN_VALUES_FOR_DUPLICATES:
        return {}
    step = max(1, H.shape[0] // _SCREEN_LINES)
    screen = np.moveaxis(H[::step], axis, 0).reshape(n, -1)
    candidates = _similar_pairs(screen, tolerance=1e-6)
    found: dict[int, int] = {}
    for i, j in candidates:  # i < j, in order
        if j in found or i in found:
            continue
        if _similar_pairs(X[[i, j]], DUPLICATE_TOLERANCE):
            found[j] = i
    return found


def _similar_pairs(X: np.ndarray, tolerance: float) -> list[tuple[int, int]]:
    """Pairs ``(i, j)``, ``i < j``, of rows of ``X`` equal up to a factor within
    ``tolerance`` (``1 - |cos|``), in order."""
    norms = np.linalg.norm(X, axis=1)
    Xn = X / np.where(norms > 0, norms, 1.0)[:, None]
    cos = np.abs(Xn.conj() @ Xn.T)
    i, j = np.nonzero(np.triu(1.0 - cos < tolerance, k=1))
    return sorted(zip(i.tolist(), j.tolist()))


def _usable_channels(
    data: FRFData, H: np.ndarray, warnings: list[str]
) -> tuple[np.ndarray, np.ndarray]:
    """Masks of the outputs and inputs to keep: not zero, not a duplicate."""
    names = {1: list(data.output_names), 2: list(data.input_names)}
    sides = {1: "output", 2: "input"}
    keep = {}
    for axis in (1, 2):
        zero = zero_channels(H, axis)
        if zero.all():
            raise InputError(f"every FRF is zero (or below {MIN_MAGNITUDE:g}): nothing to "
                             "identify", data.source)
        if zero.any():
            warnings.append(f"{sides[axis]}(s) {_names(names[axis], zero)} are zero (or below "
                            f"{MIN_MAGNITUDE:g}) over the band and were left out (dead "
                            "channels)")
        keep[axis] = ~zero
    H = H[:, keep[1]][:, :, keep[2]]
    for axis in (1, 2):
        index = np.flatnonzero(keep[axis])
        groups: dict[int, list[int]] = {}
        for dup, first in duplicate_channels(H, axis).items():
            keep[axis][index[dup]] = False
            groups.setdefault(int(index[first]), []).append(int(index[dup]))
        for first, dups in groups.items():
            mask = np.isin(np.arange(len(keep[axis])), dups)
            warnings.append(
                f"{sides[axis]}(s) {_names(names[axis], mask)} are identical to "
                f"{names[axis][first]} (up to a factor) and were left out: identical "
                f"{sides[axis]}s make the data rank-deficient")
    return keep[1], keep[2]


def _names(names: list[str], mask: np.ndarray) -> str:
    """The names selected by ``mask``, comma-separated (the first ten)."""
    chosen = [names[i] if i < len(names) else str(i + 1) for i in np.flatnonzero(mask)]
    return ", ".join(chosen[:10]) + (f" and {len(chosen) - 10} more" if len(chosen) > 10 else "")


def _select_channels(data: FRFData, keep_out: np.ndarray, keep_in: np.ndarray) -> FRFData:
    """A copy of ``data`` with only the kept outputs and inputs."""
    out, inp = np.flatnonzero(keep_out), np.flatnonzero(keep_in)

    def pick(values: list[str] | None, index: np.ndarray) -> list[str] | None:
        return None if values is None else [values[i] for i in index]

    def take(values: np.ndarray | None, index: np.ndarray, axis: int) -> np.ndarray | None:
        return None if values is None else np.take(values, index, axis=axis)

    frf = data.frf[:, out][:, :, inp]
    coherence = None if data.coherence is None else data.coherence[:, out][:, :, inp]
    records = None if data.records is None else data.records[:, :, out][:, :, :, inp]
    return dataclasses.replace(
        data,
        frf=frf,
        coherence=coherence,
        records=records,
        output_names=pick(data.output_names, out),
        input_names=pick(data.input_names, inp),
        output_nodes=take(data.output_nodes, out, 0),
        input_nodes=take(data.input_nodes, inp, 0),
        output_directions=pick(data.output_directions, out),
        input_directions=pick(data.input_directions, inp),
        output_xyz=take(data.output_xyz, out, 0),
        attributes=dict(data.attributes),
    )


def trend_decades(H: np.ndarray) -> float:
    """Decades spanned by the trend of the FRF magnitude over the band.

    Measured on the pipeline's own line weights
    (:func:`automodal.core.subspace.envelope_weights` of the channel-scaled FRFs, which
    level the trend): weights spanning ``10^(2 d)`` mean a trend of ``d`` decades. The FRFs
    are taken as the pipeline takes them: transposed when there are more inputs than
    outputs (reciprocity), which changes the channel scaling.
    """
    if H.shape[2] > H.shape[1]:
        H = H.transpose(0, 2, 1)
    Hs = H / subspace.channel_scales(H)[None, :, None]
    w = subspace.envelope_weights(Hs)
    return 0.5 * float(np.log10(np.max(w) / np.min(w)))


def identified_form(freq: np.ndarray, H: np.ndarray, power: int) -> tuple[bool, float]:
    """Whether a mobility or an accelerance is identified in its receptance form, and the
    magnitude trend (decades, :func:`trend_decades`) of the form identified.

    The models must reproduce the FRF's trend over the band, which costs states and
    precision, so the form with the smaller trend is fitted: the data as measured, or
    divided by ``(2 pi f)^power``. The whitened data, and so the statistics, are the same
    in both. An accelerance from 0.008 Hz (family seed 335, f_08) rises 7.8 decades to its
    first modes, and no model fitted it to its 5 % proportional noise; its receptance form
    spans 1.1 decades and every mode was found. With a noise floor at the lowest lines the
    measured form is the flatter one: a 0.007-43 Hz mobility with additive noise spans 1.1
    decades and its receptance form 3.0, and fitting that one lost 2 of 30 modes (seed 283,
    f_05). The trend of a part of a band cut beside a strong peak says little (a free-free
    beam's 65-975 Hz accelerance, 2.2 decades against 1.9 as a receptance, lost its first
    mode so; 65-1000 Hz, 0.97 against 1.6): the pipeline chooses once per band, and its
    sub-bands keep the choice.

    Parameters
    ----------
    freq : ndarray, shape (N,)
        Lines (Hz), positive.
    H : ndarray, shape (N, ny, nu)
    power : int
        ``p``: the FRFs are a receptance times ``(j w)^p``; 0 (a receptance, or output-only
        half spectra) is identified as it is.

    Returns
    -------
    (bool, float)
        True when the receptance form is identified (the measured form otherwise), and its
        trend in decades.
    """
    measured = trend_decades(H)
    if power == 0:
        return False, measured
    receptance = trend_decades(H / ((2.0 * np.pi * np.asarray(freq)) ** power)[:, None, None])
    return (True, receptance) if receptance < measured else (False, measured)


def _check_trend(decades: float, source: str | None, warnings: list[str]) -> None:
    """Warn about (or refuse) a magnitude trend of ``decades``."""
    advice = "narrow the band (--band FMIN FMAX)"
    if decades > MAX_TREND_DECADES:
        raise InputError(f"the FRF magnitude spans {decades:.1f} decades over the band, more "
                         f"than the {MAX_TREND_DECADES:g} the identification can weigh in "
                         f"double precision: {advice}", source)
    if decades > WARN_TREND_DECADES:
        warnings.append(f"the FRF magnitude spans {decades:.1f} decades over the band: the "
                        "identification loses precision beyond about "
                        f"{MAX_TREND_DECADES:g}; if modes are missing, {advice}")


def _log_magnitude(H: np.ndarray) -> tuple[np.ndarray, float]:
    """The natural log of the mean over channels of ``|H|`` scaled to unit RMS per output,
    and its line-to-line roughness (robust: median absolute second difference)."""
    return mean_log_magnitude(H, subspace.channel_scales(H), floor_ratio=1e-15)


def edge_peaks(H: np.ndarray) -> list[str]:
    """The band edges (``"low"``, ``"high"``) that sit on a resonance peak.

    An edge is on a peak when its line is the largest of the 5 % of the lines next to it
    (at least 3) and the magnitude falls from it over those lines by more than
    ``max(0.5, 6 s)`` on the natural-log scale (``s`` the roughness, see
    :func:`has_resonance`): a steep fall right at the edge, which neither a trend over the
    band nor the tail of a mode outside it gives.
    """
    n = H.shape[0]
    if n < 10:
        return []
    logm, roughness = _log_magnitude(H)
    k = max(3, n // 20)
    threshold = max(0.5, 6.0 * roughness)
    found = []
    for name, side in (("low", logm[: k + 1]), ("high", logm[::-1][: k + 1])):
        if side[0] >= np.max(side) and side[0] - side[-1] > threshold:
            found.append(name)
    return found


def has_resonance(H: np.ndarray) -> bool:
    """Whether the magnitude has an interior peak that stands out of the noise.

    The magnitude is the mean over channels of ``|H|`` scaled to unit RMS per output; on
    its natural log, a peak must rise above both neighbouring valleys by more than
    ``max(0.5, 6 s)``, with ``s`` the line-to-line roughness (robust: median absolute
    second difference). A maximum at the band's edge does not count.
    """
    if H.shape[0] < 3:
        return False
    logm, roughness = _log_magnitude(H)
    threshold = max(0.5, 6.0 * roughness)
    n = logm.size
    idx = np.arange(n)
    is_max = (logm >= running_max(logm, 11)) & (idx > 0) & (idx < n - 1)
    # the lowest point on each side, over up to a tenth of the band
    width = max(3, n // 10)
    left = running_min(logm, width, origin=(width - 1) // 2)
    right = running_min(logm, width, origin=-(width // 2))
    rise = logm - np.maximum(left, right)
    return bool(np.any(is_max & (rise > threshold)))
