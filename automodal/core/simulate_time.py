"""Synthetic time records of known lumped-mass systems: hammer hits, random and ambient forces.

Pure numerical functions (no I/O, nothing printed). A time test is the FRF test of
:mod:`automodal.core.simulate` measured the way a laboratory does it: forces and responses
sampled at one rate, with measurement noise, for the input stage
(:func:`automodal.core.from_time.frfdata_from_time`) to turn into FRFs. The exact modes are
those of :func:`automodal.core.simulate.exact_modes`, the same object as for the FRF route.

Exact simulation
----------------
The continuous model ``x' = A x + B f``, ``y = C x + D f``
(:func:`automodal.core.simulate.state_space`) is replaced by its discrete-time hold
equivalent (:func:`scipy.signal.cont2discrete`): with a first-order hold (``"foh"``, the
default) the force between two samples is the straight line joining them, with a
zero-order hold (``"zoh"``) it is constant. For a force of that form the samples of the
response are exact (to round-off), whatever the sample rate: nothing is integrated
numerically. The recursion runs in the eigenbasis of the discrete state matrix, one
first-order complex filter per pole (:func:`scipy.signal.lfilter`), so long records cost
little; its poles are ``exp(lambda / fs)`` with ``lambda`` the exact continuous poles.

Sample rate (:func:`default_sample_rate`)
-----------------------------------------
``fs = 2.56 * 1.25 * f_max`` (rounded up to two significant digits), ``f_max`` the highest
natural frequency. The FRF route's band ends at ``1.25 f_max`` (above the highest mode's
resonance peak and its skirt), and the input stage keeps only ``f <= fs / 2.56`` of every
spectrum, the band an analyser trusts below its anti-alias filter. There is no aliasing to
filter here: the samples are exact values of the response to the held force, whose
discrete-time model has every pole inside the band. The ``2.56`` leaves the same guard band
as a real acquisition, so that the records look like measured ones, and keeps the sampled
dynamics well resolved (at ``1.25 f_max`` there are more than 2.5 samples per period of
the highest mode).

Duration (:func:`default_duration`)
-----------------------------------
Set by the slowest decay ``sigma_min = min_r zeta_r omega_r`` (1/s) of the modes, the time
constant ``tau = 1 / sigma_min`` of the mode that rings longest, not by a tuned constant:

* hits: each hit is followed by ``ln(1 / HIT_TAIL) * tau`` seconds (``HIT_TAIL = 1e-3``: the
  slowest mode has decayed to 0.1 % of its amplitude, so a rectangular record holds the
  whole response and no exponential window is needed); ``n_hits`` such records;
* random: the Welch segment must resolve the narrowest resonance, whose half-power bandwidth
  is ``sigma_min / pi`` Hz, with :data:`LINES_PER_BANDWIDTH` lines (the Hann window's bias
  at a resonance falls like the square of the line spacing over the bandwidth); the record
  holds :data:`RANDOM_AVERAGES` such segments at 50 % overlap (the input stage's automatic
  segment, :func:`automodal.core.spectra.choose_segment`, then takes that length);
* ambient: :data:`AMBIENT_DECAYS` time constants. The random error of an output-only
  damping estimate falls like ``1 / sqrt(sigma T)`` (the number of independent decays the
  record holds); the half spectra need far more data than an H1 with measured forces.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.optimize
import scipy.signal

from automodal.core.simulate import (
    IndexLike,
    MechanicalSystem,
    Modes,
    _dofs,
    _quantity_factor,
    exact_modes,
    natural_frequencies_hz,
    state_space,
    synthetic_attributes,
)
from automodal.timedata import TimeSeries

__all__ = [
    "AMBIENT_DECAYS",
    "EXCITATIONS",
    "HIT_TAIL",
    "HOLDS",
    "LINES_PER_BANDWIDTH",
    "RANDOM_AVERAGES",
    "DiscreteModel",
    "clear_modes",
    "nearest_modes",
    "TimePlan",
    "default_duration",
    "default_pulse_width",
    "default_sample_rate",
    "half_sine_spectrum",
    "discretise",
    "half_sine_hits",
    "plan",
    "respond",
    "simulate_time_test",
    "slowest_decay",
]

EXCITATIONS = ("hits", "random", "ambient")
"""Kinds of excitation of :func:`simulate_time_test`."""

HOLDS = ("foh", "zoh")
"""Holds of :func:`discretise`: first order (linear between samples) or zero order."""

HIT_TAIL = 1e-3
"""Amplitude of the slowest mode, relative to its start, at the end of a hit's record."""

LINES_PER_BANDWIDTH = 4.0
"""Welch lines across the narrowest half-power bandwidth (random excitation)."""

RANDOM_AVERAGES = 16
"""Welch segments (50 % overlap) in a random-excitation record."""

AMBIENT_DECAYS = 2000.0
"""Record length of an ambient test in time constants of the slowest mode."""

BAND_FACTOR = 1.25
"""Top of the band over the highest natural frequency (the FRF route's default)."""

ANALYSER_RATIO = 2.56
"""Sample rate over the top of the usable band (the input stage keeps ``f <= fs / 2.56``)."""

PULSE_DROP = 0.5
"""Force spectrum of a default hammer pulse at the top of the band, relative to 0 Hz."""

_CHUNK = 1 << 16  # samples per block of the modal recursion


# ----------------------------------------------------------------------------- planning


def slowest_decay(modes: Modes) -> float:
    """``min_r (-Re lambda_r)`` in 1/s: the decay rate of the mode that rings longest.

    Raises
    ------
    ValueError
        Without a mode, or when a mode is undamped (it never dies out: no finite record
        resolves it).
    """
    if modes.n_modes == 0:
        raise ValueError("the system has no oscillatory mode")
    sigma = float(np.min(-modes.poles.real))
    if not sigma > 0:
        raise ValueError("a mode is undamped: give the system some damping (zeta > 0)")
    return sigma


def _round_up(x: float, digits: int = 2) -> float:
    """``x`` rounded up to ``digits`` significant digits."""
    step = 10.0 ** (math.floor(math.log10(x)) - digits + 1)
    return math.ceil(x / step * (1 - 1e-12)) * step


def default_sample_rate(system: MechanicalSystem) -> float:
    """``2.56 * 1.25 * f_max`` rounded up to two significant digits (see the module notes)."""
    f_max = float(natural_frequencies_hz(system).max())
    if not f_max > 0:
        raise ValueError("the system has no flexible mode")
    return _round_up(ANALYSER_RATIO * BAND_FACTOR * f_max)


def half_sine_spectrum(ft: np.ndarray | float) -> np.ndarray:
    """Spectrum magnitude of a half-sine pulse of width ``T`` at ``f``, relative to 0 Hz,
    as a function of ``f T``: ``|cos(pi f T)| / |1 - (2 f T)^2|`` (``pi / 4`` at ``f T = 1/2``;
    first zero at ``f T = 3/2``)."""
    x = np.asarray(ft, dtype=float)
    den = 1.0 - (2.0 * x) ** 2
    near = np.abs(den) < 1e-9
    return np.where(near, np.pi / 4, np.abs(np.cos(np.pi * x)) / np.where(near, 1.0, np.abs(den)))


def default_pulse_width(sample_rate: float) -> float:
    """Width (s) of a half-sine hammer pulse whose spectrum at the top of the usable band
    ``fs / 2.56`` is :data:`PULSE_DROP` (half) of its value at 0 Hz.

    The spectrum (:func:`half_sine_spectrum`) falls monotonically from 1 to its first zero
    at ``f T = 1.5`` and is one half at ``f T = 0.8195``. A harder tip (shorter pulse)
    excites more of the band; a softer one leaves the top modes with little force, as in a
    real test. At the default sample rate the pulse is about two samples wide.
    """
    ft = scipy.optimize.brentq(lambda x: float(half_sine_spectrum(x)) - PULSE_DROP, 0.0, 1.5)
    return float(ft) / (sample_rate / ANALYSER_RATIO)


@dataclass(frozen=True)
class TimePlan:
    """The sampling of a time test: rate, length, and for hits their timing.

    Attributes
    ----------
    sample_rate : float
        Hz.
    n_samples : int
        Samples per channel.
    hit_spacing : int
        Samples between hits (hits only, else 0).
    first_hit : int
        Sample of the first hit's onset (a pre-trigger of 5 % of the spacing).
    n_hits : int
        Number of hits (0 unless hits).
    pulse_width : float
        Width of a hammer pulse in s (hits only, else 0).
    rule : dict
        How the duration was set (JSON-friendly), for the modes file.
    """

    sample_rate: float
    n_samples: int
    hit_spacing: int = 0
    first_hit: int = 0
    n_hits: int = 0
    pulse_width: float = 0.0
    rule: dict[str, Any] = field(default_factory=dict)

    @property
    def duration(self) -> float:
        """Record length in s."""
        return self.n_samples / self.sample_rate


def default_duration(
    excitation: str, sigma_min: float, sample_rate: float, n_hits: int = 5
) -> tuple[float, dict[str, Any]]:
    """The record length (s) of a test by the rules of the module notes, and the rule.

    Parameters
    ----------
    excitation : {"hits", "random", "ambient"}
    sigma_min : float
        Slowest decay rate of the modes, 1/s (:func:`slowest_decay`).
    sample_rate : float
        Hz.
    n_hits : int
        Number of hits (hits only).

    Returns
    -------
    duration : float
        Seconds.
    rule : dict
        The rule and its numbers, JSON-friendly.
    """
    _check_excitation(excitation)
    tau = 1.0 / sigma_min
    if excitation == "hits":
        spacing = math.log(1.0 / HIT_TAIL) * tau
        rule = {"rule": "n_hits records of ln(1/HIT_TAIL) time constants", "tau_s": tau,
                "hit_tail": HIT_TAIL, "hit_spacing_s": spacing}
        return (n_hits + 0.05) * spacing, rule
    if excitation == "random":
        segment_s = LINES_PER_BANDWIDTH * math.pi * tau  # df = bandwidth / lines
        nperseg = 2 ** math.ceil(math.log2(segment_s * sample_rate))
        n = (RANDOM_AVERAGES + 1) * nperseg // 2  # 50 % overlap
        rule = {"rule": "RANDOM_AVERAGES Welch segments with LINES_PER_BANDWIDTH lines "
                "across the narrowest half-power bandwidth", "tau_s": tau,
                "lines_per_bandwidth": LINES_PER_BANDWIDTH, "averages": RANDOM_AVERAGES,
                "nperseg": nperseg}
        return n / sample_rate, rule
    rule = {"rule": "AMBIENT_DECAYS time constants of the slowest mode", "tau_s": tau,
            "decays": AMBIENT_DECAYS}
    return AMBIENT_DECAYS * tau, rule


def plan(
    excitation: str,
    modes: Modes,
    sample_rate: float,
    duration: float | None = None,
    n_hits: int = 5,
    pulse_width: float | None = None,
) -> TimePlan:
    """The sampling of a test: the given or default duration, hit timing and pulse width.

    With hits and a given ``duration``, the hits share it evenly (each record
    ``duration / (n_hits + 0.05)``, the 0.05 a pre-trigger before the first hit).

    Raises
    ------
    ValueError
        On a bad excitation, count, rate or width, a record shorter than 64 samples, or
        hits so close that a record holds fewer than 64 samples or less than two pulses.
    """
    _check_excitation(excitation)
    if not (np.isfinite(sample_rate) and sample_rate > 0):
        raise ValueError("the sample rate must be > 0")
    if excitation == "hits" and n_hits < 1:
        raise ValueError("need at least one hit")
    sigma = slowest_decay(modes)
    auto, rule = default_duration(excitation, sigma, sample_rate, n_hits)
    if duration is None:
        duration = auto
    else:
        rule = {"rule": "given", "tau_s": 1.0 / sigma, "default_s": auto}
    if not (np.isfinite(duration) and duration > 0):
        raise ValueError("the duration must be > 0")
    n = int(round(duration * sample_rate))
    if n < 64:
        raise ValueError(f"{n} samples are too few (at least 64): a longer duration or a "
                         "higher sample rate")
    if excitation != "hits":
        return TimePlan(sample_rate, n, rule=rule)
    width = default_pulse_width(sample_rate) if pulse_width is None else float(pulse_width)
    if not (np.isfinite(width) and width > 0):
        raise ValueError("the pulse width must be > 0")
    spacing = int(n / (n_hits + 0.05))
    if spacing < 64 or width * sample_rate > spacing / 2:
        raise ValueError(f"{n_hits} hits in {n} samples leave {spacing} samples per hit: "
                         "too few for a record (at least 64, and two pulse widths)")
    first = max(1, int(math.ceil(0.05 * spacing)))
    rule = {**rule, "hit_spacing_s": spacing / sample_rate}
    return TimePlan(sample_rate, first + n_hits * spacing, spacing, first, n_hits, width,
                    rule)


# ------------------------------------------------------------------------- simulation


@dataclass(frozen=True)
class DiscreteModel:
    """The hold equivalent of a continuous model, in its eigenbasis.

    ``x[k+1] = Ad x[k] + Bd u[k]``, ``y[k] = Cd x[k] + Dd u[k]`` with ``Ad = V diag(z) V^-1``;
    the recursion runs on ``V^-1 x`` (one first-order filter per eigenvalue ``z``).
    """

    Ad: np.ndarray
    Bd: np.ndarray
    Cd: np.ndarray
    Dd: np.ndarray
    sample_rate: float
    z: np.ndarray  # eigenvalues of Ad
    modal_B: np.ndarray  # V^-1 Bd, (n_states, n_in)
    modal_C: np.ndarray  # Cd V, (n_out, n_states)


def discretise(
    system: MechanicalSystem,
    outputs: IndexLike,
    inputs: IndexLike,
    quantity: str,
    sample_rate: float,
    hold: str = "foh",
) -> DiscreteModel:
    """The exact discrete-time model of the system for a force held between samples.

    Parameters
    ----------
    system : MechanicalSystem
    outputs, inputs : int or sequence of int
        0-based sensor and force DOFs.
    quantity : {"displacement", "velocity", "acceleration"}
    sample_rate : float
        Hz.
    hold : {"foh", "zoh"}
        The force between samples: linear (first-order hold) or constant (zero-order).

    Returns
    -------
    DiscreteModel
    """
    if hold not in HOLDS:
        raise ValueError(f"hold must be one of {HOLDS}, got {hold!r}")
    A, B, C, D = state_space(system, outputs, inputs, quantity)
    Ad, Bd, Cd, Dd, _ = scipy.signal.cont2discrete((A, B, C, D), 1.0 / sample_rate, hold)
    z, V = np.linalg.eig(Ad)
    return DiscreteModel(Ad, Bd, Cd, Dd, float(sample_rate), z, np.linalg.solve(V, Bd),
                         Cd @ V)


def respond(model: DiscreteModel, u: np.ndarray) -> np.ndarray:
    """Response of the discrete model, from rest, to the force samples ``u``.

    Parameters
    ----------
    model : DiscreteModel
    u : ndarray, shape (n_samples, n_in)

    Returns
    -------
    ndarray, shape (n_samples, n_out)
        ``y[k] = Cd x[k] + Dd u[k]`` with ``x[0] = 0``.
    """
    u = np.asarray(u, dtype=float)
    if u.ndim != 2 or u.shape[1] != model.Bd.shape[1]:
        raise ValueError(f"u must be (n_samples, {model.Bd.shape[1]}), got {u.shape}")
    n_states = model.z.size
    y = u @ model.Dd.T
    # q = V^-1 x obeys q[k] = z q[k-1] + w[k-1] with w[k] = V^-1 Bd u[k]: each state is the
    # first-order filter (0 + z^-1) / (1 - z z^-1) of its w; its final filter state carries
    # the recursion from one block to the next.
    carry = np.zeros((n_states, 1), dtype=complex)
    for s in range(0, u.shape[0], _CHUNK):
        w = u[s : s + _CHUNK] @ model.modal_B.T
        q = np.empty_like(w)
        for i in range(n_states):
            q[:, i], carry[i] = scipy.signal.lfilter([0.0, 1.0], [1.0, -model.z[i]], w[:, i],
                                                     zi=carry[i])
        y[s : s + _CHUNK] += (q @ model.modal_C.T).real
    return y


# ---------------------------------------------------------------------------- forces


def half_sine_hits(
    time_plan: TimePlan, rng: np.random.Generator, amplitude: float = 1.0
) -> np.ndarray:
    """Hammer forces: one half-sine pulse per hit, zero in between.

    Hit ``k`` starts at sample ``first_hit + k * hit_spacing`` plus a random fraction of a
    sample (so that each hit is sampled differently, as in a real test), with a peak drawn
    uniformly in ``[amplitude / 2, amplitude]``. The samples are those of the continuous
    pulse ``A sin(pi (t - t0) / T)`` on ``[t0, t0 + T]``.

    Returns
    -------
    ndarray, shape (n_samples, 1)
    """
    fs, width = time_plan.sample_rate, time_plan.pulse_width
    f = np.zeros((time_plan.n_samples, 1))
    span = int(math.ceil(width * fs)) + 2
    for k in range(time_plan.n_hits):
        onset = time_plan.first_hit + k * time_plan.hit_spacing
        t0 = onset + rng.uniform(0.0, 1.0)
        peak = rng.uniform(0.5 * amplitude, amplitude)
        idx = np.arange(onset, min(onset + span, time_plan.n_samples))
        phase = (idx - t0) / (width * fs)
        inside = (phase > 0) & (phase < 1)
        f[idx[inside], 0] = peak * np.sin(np.pi * phase[inside])
    return f


def _with_noise(x: np.ndarray, level: float, rng: np.random.Generator) -> np.ndarray:
    """``x`` plus white Gaussian noise of std ``level`` times each channel's RMS."""
    rms = np.sqrt(np.mean(x**2, axis=0, keepdims=True))
    return x + level * rms * rng.standard_normal(x.shape)


def _check_excitation(excitation: str) -> None:
    if excitation not in EXCITATIONS:
        raise ValueError(f"excitation must be one of {EXCITATIONS}, got {excitation!r}")


# ------------------------------------------------------------------------- whole test


def simulate_time_test(
    system: MechanicalSystem,
    outputs: IndexLike,
    inputs: IndexLike,
    excitation: str,
    quantity: str = "displacement",
    noise: float = 0.01,
    seed: int | None = None,
    sample_rate: float | None = None,
    duration: float | None = None,
    n_hits: int = 5,
    pulse_width: float | None = None,
    hold: str = "foh",
    max_values: int | None = None,
) -> tuple[TimeSeries, Modes, TimePlan]:
    """A synthetic time test of a known system, and its exact modes.

    Parameters
    ----------
    system : MechanicalSystem
        Damped (every mode must decay).
    outputs : int or sequence of int
        0-based sensor DOFs.
    inputs : int or sequence of int
        0-based force DOFs: the one hammer DOF (hits), the shakers (random), or the DOFs
        where unmeasured ambient forces act (ambient).
    excitation : {"hits", "random", "ambient"}
        ``"hits"``: ``n_hits`` half-sine hammer pulses (:func:`half_sine_hits`), each
        followed by the free decay of the response; ``"random"``: independent white
        Gaussian force samples, measured (the samples are white up to ``fs / 2``, the
        band-limited white noise of a shaker test; burst random is not simulated);
        ``"ambient"``: independent white Gaussian forces, not measured (the series has no
        inputs).
    quantity : {"displacement", "velocity", "acceleration"}
        The response measured.
    noise : float
        Measurement noise on every channel, forces included: white Gaussian with std
        ``noise`` times the channel's RMS (0.01 = 1 %).
    seed : int, optional
        Seed of ``numpy.random.default_rng``; the same seed gives the same samples. When
        ``None`` one is drawn; it is recorded in the attributes.
    sample_rate, duration : float, optional
        Hz and s; defaults :func:`default_sample_rate` and :func:`default_duration`.
    n_hits : int
        Number of hammer hits.
    pulse_width : float, optional
        Width of a hammer pulse in s; default :func:`default_pulse_width`.
    hold : {"foh", "zoh"}
        The force between samples (:func:`discretise`).
    max_values : int, optional
        Most samples (over all channels) to simulate; more is refused before any work.

    Returns
    -------
    series : TimeSeries
        Channels ``dofN``; attributes ``quantity``, ``structure``, ``generator``, ``seed``,
        ``noise_level``, ``excitation``, ``hold``, ``damping``.
    modes : Modes
        :func:`automodal.core.simulate.exact_modes` at the outputs, with residues for the
        inputs.
    plan : TimePlan
        The sampling used.

    Raises
    ------
    ValueError
        On a bad argument (see :func:`plan`), more than one hammer DOF, a negative
        noise level, or more than ``max_values`` samples.
    """
    _check_excitation(excitation)
    n = system.n_dof
    out, inp = _dofs(outputs, n, "output DOF"), _dofs(inputs, n, "input DOF")
    if excitation == "hits" and inp.size != 1:
        raise ValueError("a hammer test hits one DOF at a time: give one input")
    if not (np.isfinite(noise) and noise >= 0):
        raise ValueError("noise level must be >= 0")
    if seed is None:
        seed = int(np.random.SeedSequence().generate_state(1)[0])
    rng = np.random.default_rng(seed)
    modes = exact_modes(system, out, inp)
    fs = default_sample_rate(system) if sample_rate is None else float(sample_rate)
    time_plan = plan(excitation, modes, fs, duration, n_hits, pulse_width)
    n_channels = out.size + (0 if excitation == "ambient" else inp.size)
    if max_values is not None and time_plan.n_samples * n_channels > max_values:
        raise ValueError(
            f"{time_plan.n_samples} samples of {n_channels} channels are more than the"
            f" {max_values} values automodal reads back: shorten the records or lower the"
            " sample rate")
    if excitation == "hits":
        force = half_sine_hits(time_plan, rng)
    else:
        force = rng.standard_normal((time_plan.n_samples, inp.size))
    model = discretise(system, out, inp, quantity, fs, hold)
    y = _with_noise(respond(model, force), noise, rng)
    measured = None if excitation == "ambient" else _with_noise(force, noise, rng)
    attributes = {
        "quantity": quantity,
        **synthetic_attributes(system, seed, noise),
        "excitation": excitation,
        "hold": hold,
    }
    series = TimeSeries(
        outputs=y,
        inputs=measured,
        sample_rate=fs,
        output_names=[f"dof{i + 1}" for i in out],
        input_names=[] if measured is None else [f"dof{j + 1}" for j in inp],
        attributes=attributes,
    )
    return series, modes, time_plan


# ------------------------------------------------------------------------ truth checks


def clear_modes(
    modes: Modes, band_top_hz: float, quantity: str = "displacement", share: float = 0.01
) -> np.ndarray:
    """The exact modes a test shows clearly: those a truth test may demand to be found.

    A mode is clear when its natural frequency is at most ``band_top_hz`` (the analysed
    band) and its resonance peak in the measured quantity, ``|lambda|^p max |R| / sigma``
    (``p`` = 0, 1, 2 for displacement, velocity, acceleration; ``R`` the residues, ``sigma``
    the decay rate), is at least ``share`` of the largest mode's.

    Returns
    -------
    ndarray of int
        Indices into ``modes``.
    """
    if modes.residues is None:
        raise ValueError("the modes have no residues (give the inputs to exact_modes)")
    if modes.n_modes == 0:
        return np.zeros(0, dtype=int)
    gain = np.abs(_quantity_factor(np.abs(modes.poles), quantity))
    peak = np.abs(modes.residues).reshape(modes.n_modes, -1).max(axis=1) * gain
    peak = peak / -modes.poles.real
    return np.flatnonzero((modes.frequency_hz <= band_top_hz) & (peak >= share * peak.max()))


def nearest_modes(true_hz: np.ndarray, found_hz: np.ndarray, tol: float = 0.01) -> np.ndarray:
    """For each true frequency, the index of the nearest found one within the relative
    tolerance ``tol``, or -1."""
    true_hz = np.asarray(true_hz, dtype=float).reshape(-1)
    found_hz = np.asarray(found_hz, dtype=float).reshape(-1)
    out = np.full(true_hz.size, -1)
    if found_hz.size:
        k = np.argmin(np.abs(found_hz[None, :] - true_hz[:, None]), axis=1)
        ok = np.abs(found_hz[k] / true_hz - 1) < tol
        out[ok] = k[ok]
    return out
