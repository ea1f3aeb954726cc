"""Property-based tests of the input readers (issue 7): hostile files never crash them.

Every generated input (HDF5 FRF files of random shapes, dtypes, values and attributes, with
optional damage; CSV tables; NPZ archives; UFF files; raw bytes) either reads into a valid
:class:`~automodal.frfdata.FRFData` or is refused with one :class:`InputError` line that
names the file (``docs/frf-file.md``). Nothing else may escape :func:`read_any`, the input
file is never changed and nothing is written beside it. A sample of the inputs also goes
through ``automodal identify`` in a subprocess: exit 2 with one line on stderr, no traceback
and no report for a refused input; exit 0 with a complete report, or exit 2 as above, for
one that reads.

Profiles: ``ci`` (the default: 80 examples per reader test, fewer for the slower UFF,
pipeline and command-line tests; about 15 s in all) and ``long`` (2000 per reader test,
1000 UFF files, 600 identifications and 300 command-line runs; about 4 minutes)::

    HYPOTHESIS_PROFILE=long python -m pytest tests/test_hypothesis_readers.py
"""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
import tempfile
import zipfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest
import pyuff
from hypothesis import HealthCheck, event, given, note, settings
from hypothesis import strategies as st

from automodal.core.from_time import as_frfdata
from automodal.errors import InputError
from automodal.frfdata import QUANTITIES, FRFData
from automodal.io.readers import read_any

# ----------------------------------------------------------------------------- profiles

_COMMON: dict[str, Any] = {
    "deadline": None,  # file creation and HDF5 opens vary a lot on a busy CI machine
    "suppress_health_check": [HealthCheck.too_slow, HealthCheck.data_too_large],
    "print_blob": True,
}
settings.register_profile("ci", max_examples=80, **_COMMON)
settings.register_profile("long", max_examples=2000, **_COMMON)
PROFILE = os.environ.get("HYPOTHESIS_PROFILE", "ci")
"""The active profile: ``ci`` unless the environment variable ``HYPOTHESIS_PROFILE`` names
another registered one."""
_BASE = settings.get_profile(PROFILE)


def examples(share: float) -> settings:
    """The active profile with ``share`` of its examples (at least 4), for costly tests.

    Parameters
    ----------
    share : float
        Fraction of the profile's ``max_examples``.

    Returns
    -------
    hypothesis.settings
    """
    return settings(_BASE, max_examples=max(4, int(round(_BASE.max_examples * share))))


@pytest.fixture(scope="module", autouse=True)
def read_time_limit() -> Iterator[None]:
    """A shorter limit on reading one file (:data:`automodal.io.readers.READ_TIMEOUT_S`):
    a file that makes the HDF5 library loop costs 20 s, not 2 minutes."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("AUTOMODAL_READ_TIMEOUT_S", "20")
        yield


# ------------------------------------------------------------------------------ inputs


@dataclass
class Input:
    """A generated input file: how to write it and what it is.

    Attributes
    ----------
    suffix : str
        The file name's suffix (it chooses the reader).
    make : callable
        ``make(path)`` writes the file.
    """

    suffix: str
    make: Callable[[Path], None]

    def write(self, folder: Path) -> Path:
        """Write the input as ``folder/input<suffix>`` and return its path."""
        path = folder / f"input{self.suffix}"
        self.make(path)
        return path


SPECIAL_VALUES = (np.nan, np.inf, -np.inf, 0.0, -0.0, 1e308, -1e308, 5e-324, 1e-300, 1e300,
                  3.5e38)
"""Floats that break naive code: non-finite, zero, subnormal, near overflow (of float32 too)."""

FINITE_SPECIALS = (0.0, -0.0, 5e-324, 1e-300, 1e-12, 1e3, 1e100, 1e150, 3.5e38)
"""The finite ones (and a few extreme but ordinary magnitudes), for inputs that must read."""

SCALES = (1.0, 1e-12, 1e3, 1e-300, 1e100, 1e300)
"""Magnitudes of generated values (the first is the ordinary one)."""

NUMERIC_DTYPES = ("c16", "c8", "f8", "f4", "f2", "i8", "i1", "u8", "bool")
"""Dtypes of generated numeric arrays (the first is the ordinary one)."""

OTHER_DTYPES = ("S8", "str", "ri", "compound")
"""Non-numeric dtypes: fixed bytes, UTF-8 strings, a compound of (r, i) floats (which h5py
reads as complex) and another compound."""


def pick(draw: st.DrawFn, good: list[Any], bad: list[Any], clean: bool) -> Any:
    """One of ``good`` (repeated so that it is drawn about two times in three), or of
    ``bad`` too unless ``clean``. Good values come first, so examples shrink towards them."""
    return draw(st.sampled_from(good if clean else good * (1 + len(bad) // len(good)) + bad))


class Faults:
    """Which parts of a generated input may be broken.

    A third of the inputs are clean (every part valid), a third have one broken part, a
    third may have any part broken: enough valid files reach the reader's success path.

    Parameters
    ----------
    draw : callable
        Hypothesis' draw function.
    parts : sequence of str
        The parts of the input.
    mode : {"clean", "one", "any"} or None
        Forced mode; drawn when None.
    """

    def __init__(self, draw: st.DrawFn, parts: tuple[str, ...], mode: str | None = None):
        mode = mode or draw(st.sampled_from(["clean", "one", "any"]))
        if mode == "clean":
            self.broken: set[str] = set()
        elif mode == "one":
            self.broken = {draw(st.sampled_from(parts))}
        else:
            self.broken = set(parts)
        note(f"faults allowed in: {sorted(self.broken) or 'nothing'}")

    def clean(self, part: str) -> bool:
        """Whether ``part`` must be valid."""
        return part not in self.broken

    def pick(self, draw: st.DrawFn, part: str, good: list[Any], bad: list[Any]) -> Any:
        """:func:`pick` for ``part``."""
        return pick(draw, good, bad, self.clean(part))


@st.composite
def arrays(draw: st.DrawFn, shape: tuple[int, ...], dtypes: tuple[str, ...] = NUMERIC_DTYPES,
           specials: tuple[float, ...] = SPECIAL_VALUES) -> np.ndarray:
    """A numpy array of ``shape`` and a drawn dtype, with drawn special values in it.

    Parameters
    ----------
    draw : callable
        Hypothesis' draw function.
    shape : tuple of int
        Shape of the array.
    dtypes : tuple of str
        Dtype names to choose from (see :data:`NUMERIC_DTYPES`, :data:`OTHER_DTYPES`);
        ``"clongdouble"`` is allowed too.
    specials : tuple of float
        Values that may be put in at drawn places (none when empty).

    Returns
    -------
    ndarray
    """
    kind = draw(st.sampled_from(dtypes))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    scale = draw(st.sampled_from(SCALES))
    size = int(np.prod(shape))
    if kind == "S8":
        return np.array([b"w%d" % i for i in range(size)], dtype="S8").reshape(shape)
    if kind == "str":
        words = ["tip", "\u00e9t\u00e9", "", "a b", "\U0001f600", "x" * 40]
        return np.array([words[i % len(words)] for i in range(size)],
                        dtype=h5py.string_dtype()).reshape(shape)
    if kind in ("ri", "compound"):
        fields = [("r", "<f8"), ("i", "<f8")] if kind == "ri" else [("a", "<f8"), ("b", "<i4")]
        out = np.zeros(shape, dtype=fields)
        out[fields[0][0]] = rng.standard_normal(shape)
        return out
    with np.errstate(over="ignore", invalid="ignore"):
        values = rng.standard_normal(shape) * scale
        if kind in ("c16", "c8", "clongdouble"):
            values = values + 1j * rng.standard_normal(shape) * scale
        put_specials(draw, values, specials)
        if kind == "bool":
            return values.real > 0
        if kind[0] in "iu":
            info = np.iinfo(kind)
            return np.clip(np.nan_to_num(values.real), info.min, info.max).astype(kind)
        cast = values.astype(kind)
        if np.all(np.isfinite(values)) and not np.all(np.isfinite(cast)):
            return values  # finite values asked for: keep the wider dtype (float32 overflow)
        return cast


def put_specials(draw: st.DrawFn, values: np.ndarray, specials: tuple[float, ...]) -> None:
    """Put up to three drawn ``specials`` at drawn places of ``values`` (in place; into
    the real or imaginary part of a complex array)."""
    flat = values.reshape(-1)
    if not specials or not flat.size:
        return
    for _ in range(draw(st.integers(0, 3))):
        index = draw(st.integers(0, flat.size - 1))
        value = draw(st.sampled_from(specials))
        if np.iscomplexobj(flat) and draw(st.booleans()):
            flat[index] = complex(flat[index].real, value)
        else:
            flat[index] = value


GOOD_FREQUENCIES = ["even", "uneven", "zero_start"]
BAD_FREQUENCIES = ["random", "repeated", "decreasing", "negative", "special", "length", "2d",
                   "scalar", "int", "complex", "float32_tiny", "strings", "huge"]


@st.composite
def frequencies(draw: st.DrawFn, n: int, clean: bool = False) -> np.ndarray:
    """A frequency axis of ``n`` lines: valid, or (unless ``clean``) broken in one way.

    Returns
    -------
    ndarray
        Valid kinds: even from a start > 0, uneven but increasing, even from 0 Hz. Broken
        kinds (:data:`BAD_FREQUENCIES`): random order, a repeated line, decreasing,
        negative, non-finite, a wrong length or dimension, integer, complex or string
        dtype, lines that float32 cannot tell apart, values near overflow.
    """
    kind = pick(draw, GOOD_FREQUENCIES, BAD_FREQUENCIES, clean)
    start = draw(st.sampled_from([1.0, 0.5, 1e-9, 100.0]))
    step = draw(st.sampled_from([0.25, 1.0, 1e-6, 10.0]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    even = start + np.arange(n) * step
    if kind == "even":
        return even
    if kind == "uneven":
        return start + np.cumsum(rng.uniform(1e-3, 5.0, n))
    if kind == "zero_start":
        return np.arange(n) * step
    if kind == "random":
        return rng.uniform(-1.0, 100.0, n)
    if kind == "repeated":
        if n >= 2:
            k = draw(st.integers(1, n - 1))
            even[k] = even[k - 1]
        return even
    if kind == "decreasing":
        return even[::-1].copy()
    if kind == "negative":
        return even - 3.0
    if kind == "special":
        if n:
            even[draw(st.integers(0, n - 1))] = draw(st.sampled_from(SPECIAL_VALUES))
        return even
    if kind == "length":
        return start + np.arange(max(0, n + draw(st.sampled_from([-1, 1, 5]))), dtype=float)
    if kind == "2d":
        return even.reshape(1, -1)
    if kind == "scalar":
        return np.float64(start)
    if kind == "int":
        return np.arange(n, dtype=np.int32) + 1
    if kind == "complex":
        return even + 0j
    if kind == "float32_tiny":  # strictly increasing in float64, repeated in float32
        return (1.0 + np.arange(n) * 1e-9).astype(np.float32)
    if kind == "strings":
        return np.array([str(x) for x in even], dtype=h5py.string_dtype())
    return even * 1e300


ATTRIBUTE_VALUES: dict[str, tuple[list[Any], list[Any]]] = {
    "format": (["automodal-frf", b"automodal-frf"],
               ["AUTOMODAL-FRF", "", "other", 1, h5py.Empty("f8"), np.bytes_(b"\xff\xfe"),
                np.array(["automodal-frf"], dtype=h5py.string_dtype())]),
    "version": ([1, 1.0, np.int8(1), np.uint64(1)],
                [2, 0, -1, 1.5, "1", b"1", True, np.nan, np.inf, np.array([1, 1]),
                 h5py.Empty("i4"), np.uint64(2**64 - 1), 1 + 0j]),
    "quantity": ([*QUANTITIES, b"velocity"],
                 ["Displacement", "", "force", 3, h5py.Empty("f8"), np.bytes_(b"\xffaccel"),
                  np.array(["displacement"], dtype=h5py.string_dtype())]),
    "window_decay_per_s": ([0.0, 0.5, 3.0, np.float32(2.0), 7],
                           [-1.0, np.nan, np.inf, "fast", np.array([1.0, 2.0]), True,
                            h5py.Empty("f8"), 1e300]),
    "test_date": (["2024-05-01T10:30:00", "2024-13-45", "", "yesterday", 20240501, np.nan,
                   np.bytes_(b"\xff")], []),
    "structure": (["beam", "\u00e9t\u00e9 \U0001f600", np.bytes_(b"\xc3\x28"), 1 + 2j,
                   np.zeros((2, 3)), np.array([(1.0, 2)], dtype=[("a", "f8"), ("b", "i4")]),
                   np.array([True, False]), h5py.Empty("S1"), np.arange(5000.0)], []),
}
"""Values tried for each root attribute: (legal, illegal). Free attributes (``test_date``,
``structure``) may hold anything; ``window_decay_per_s`` is read by the pipeline."""


@st.composite
def root_attributes(draw: st.DrawFn, clean: bool = False) -> dict[str, Any]:
    """Root attributes: each of :data:`ATTRIBUTE_VALUES` absent or with a drawn value."""
    chosen = {}
    for key, (good, bad) in ATTRIBUTE_VALUES.items():
        if draw(st.booleans()):
            chosen[key] = pick(draw, good, bad, clean)
    return chosen


EDGES = ("none", "zero_channel", "identical_outputs", "all_zero", "dc_line", "magnitudes")
"""Legal but awkward FRF content: a dead channel, identical outputs, nothing but zeros,
a 0 Hz line, values spanning 1e-12 to 1e3."""


@st.composite
def simulated_frf(draw: st.DrawFn, n: int, ny: int, nu: int) -> tuple[np.ndarray, np.ndarray]:
    """Lines and a noisy FRF of a small damped chain seen by ``ny`` sensors and ``nu``
    forces, possibly with a legal but awkward twist (:data:`EDGES`)."""
    from automodal.core import simulate as sim

    n_dof = max(ny, nu, draw(st.sampled_from([3, 2, 5])))
    system = sim.damp(sim.chain(n_dof), zeta=draw(st.sampled_from([0.01, 0.05, 1e-4])))
    top = sim.natural_frequencies_hz(system).max() * draw(st.sampled_from([1.25, 0.5, 3.0]))
    lines = sim.frequency_lines(top, max(n, 2))[:n]
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    H = sim.add_noise(sim.frf(system, lines, range(ny), range(nu)),
                      draw(st.sampled_from([0.01, 0.0, 0.2])), rng)
    edge = draw(st.sampled_from(EDGES))
    if edge == "zero_channel":
        H[:, draw(st.integers(0, ny - 1))] = 0.0
    elif edge == "identical_outputs":
        H[:] = H[:, :1]
    elif edge == "all_zero":
        H[:] = 0.0
    elif edge == "dc_line":
        lines = lines - lines[0]
    elif edge == "magnitudes":
        H = H * np.logspace(-12, 3, n)[:, None, None] / np.abs(H).max(axis=(1, 2))[:, None, None]
    note(f"simulated: {n_dof} DOF, {n} lines to {top:.3g} Hz, edge {edge}")
    return lines, H


HDF5_PARTS = ("shape", "frf", "frequency", "optional", "attributes", "time", "damage")
"""Parts of an HDF5 input that :class:`Faults` may break."""


@st.composite
def hdf5_layouts(draw: st.DrawFn, mode: str | None = None) -> dict[str, Any]:
    """The content of an HDF5 input: datasets by name (or ``"group"``), root attributes,
    the ``/time`` group, huge declared datasets.

    Parameters
    ----------
    mode : {"clean", "one", "any"} or None
        Which parts may be broken (see :class:`Faults`); ``"clean"`` gives only layouts
        that the spec allows (a valid FRF file, maybe with awkward content).

    Returns
    -------
    dict
        ``datasets`` (name -> ndarray, ``"group"`` for a group in its place, or
        ``("huge", shape, dtype)`` for a chunked dataset declared huge and never written),
        ``attributes`` (name -> value) and ``time`` (None or a dict like ``datasets``, with
        ``sample_rate``).
    """
    faults = Faults(draw, HDF5_PARTS, mode)
    n = faults.pick(draw, "shape", [40, 8, 150, 1, 2, 3, 13], [0])
    ny = faults.pick(draw, "shape", [2, 1, 3, 4], [0])
    nu = faults.pick(draw, "shape", [1, 2, 3], [0])
    ndim = faults.pick(draw, "shape", [3], [0, 1, 2, 4])
    frf_shape = (n, ny, nu, 2)[:ndim] if ndim < 4 else (2, n, ny, nu)
    datasets: dict[str, Any] = {}
    frf_kind = faults.pick(draw, "frf", ["simulated", "array"], ["absent", "group", "huge",
                                                                 "other"])
    clean = faults.clean("frf")
    if frf_kind == "simulated" and ndim == 3 and min(n, ny, nu) > 0:
        datasets["frequency"], H = draw(simulated_frf(n, ny, nu))
        specials = FINITE_SPECIALS if clean else SPECIAL_VALUES
        put_specials(draw, H, specials)
        with np.errstate(over="ignore"):
            narrow = H.astype(np.complex64)
        datasets["frf"] = narrow if draw(st.booleans()) and np.all(np.isfinite(narrow)) else H
    elif frf_kind in ("simulated", "array"):
        dtypes = ("c16", "c8") if clean else NUMERIC_DTYPES
        specials = FINITE_SPECIALS if clean else SPECIAL_VALUES
        datasets["frf"] = draw(arrays(frf_shape, dtypes, specials))
    elif frf_kind == "group":
        datasets["frf"] = "group"
    elif frf_kind == "huge":
        datasets["frf"] = ("huge", (2**27 + 1, 2, 1), "c16")
    elif frf_kind == "other":
        datasets["frf"] = draw(arrays(frf_shape, OTHER_DTYPES))
    freq_kind = faults.pick(draw, "frequency", ["array"], ["absent", "group", "huge"])
    if "frequency" in datasets:
        pass
    elif freq_kind == "array":
        datasets["frequency"] = draw(frequencies(n, faults.clean("frequency")))
    elif freq_kind == "group":
        datasets["frequency"] = "group"
    elif freq_kind == "huge":
        datasets["frequency"] = ("huge", (2**28,), "f8")
    shape3 = (n, ny, nu)
    wrong = (n, ny + 1, nu)

    clean = faults.clean("optional")

    def shapes(*bad: tuple[int, ...]) -> tuple[int, ...]:
        return pick(draw, [shape3], list(bad), clean)

    optional = {
        "coherence": lambda: _coherence(draw, shapes(wrong), clean),
        "records/frf": lambda: arrays(pick(draw, [(2, *shape3), (3, *shape3)],
                                           [(0, *shape3), (1, *wrong)], clean), ("c16",),
                                      () if clean else SPECIAL_VALUES),
        "outputs/name": lambda: arrays((pick(draw, [ny], [ny + 1], clean),),
                                       pick(draw, [("str", "S8")], [("i4",)], clean)),
        "outputs/node": lambda: arrays((pick(draw, [ny], [0], clean),),
                                       pick(draw, [("i8", "u8")], [("f8", "str")], clean)),
        "outputs/direction": lambda: arrays((ny,), pick(draw, [("str", "S8")], [("f4",)],
                                                        clean)),
        "outputs/xyz": lambda: arrays(pick(draw, [(ny, 3)], [(ny, 2), (3,)], clean),
                                      pick(draw, [("f8", "i4")], [("c16", "str")], clean),
                                      () if clean else SPECIAL_VALUES),
        "inputs/name": lambda: arrays((pick(draw, [nu], [nu + 2], clean),), ("str", "S8")),
        "inputs/node": lambda: arrays((nu,), pick(draw, [("i4", "u8")], [("bool",)], clean)),
        "inputs/direction": lambda: arrays((nu,), ("str",)),
    }
    for name, strategy in optional.items():
        if draw(st.integers(0, 4)) == 4:
            datasets[name] = draw(strategy())
    H = datasets.get("frf")
    noise = datasets.get("records/frf")
    if (clean and noise is not None and isinstance(H, np.ndarray)
            and np.issubdtype(H.dtype, np.number) and H.shape == noise.shape[1:]):
        # valid records are measurements of the FRF (when it is a valid one, not a drawn
        # fault such as strings or another shape): it times a little noise
        datasets["records/frf"] = (H.astype(complex)[None] * (1.0 + 0.01 * noise / np.maximum(
            np.abs(noise), 1e-300))).astype(noise.dtype)
    if not clean and draw(st.integers(0, 12)) == 12:  # a dataset where a group belongs,
        name = draw(st.sampled_from(["outputs", "inputs", "records", "records/frf",  # or the
                                     "coherence"]))                                  # reverse
        datasets[name] = draw(st.sampled_from([np.zeros(3), "group"]))
    if not clean and draw(st.integers(0, 15)) == 15:
        datasets["records/frf"] = ("huge", (64, 2**21, 1, 1), "c16")
    time = None if faults.clean("time") or draw(st.booleans()) else draw(time_groups())
    if time is not None and draw(st.booleans()):
        datasets.pop("frf", None)
    attributes = draw(root_attributes(faults.clean("attributes")))
    return {"datasets": datasets, "attributes": attributes, "time": time,
            "damage": not faults.clean("damage")}


def _coherence(draw: st.DrawFn, shape: tuple[int, ...], clean: bool) -> st.SearchStrategy:
    """Coherence values in [0, 1] (or, unless ``clean``, outside it or of a wrong dtype)."""
    if clean:
        return st.just(np.random.default_rng(0).uniform(0.0, 1.0, shape))
    return arrays(shape, ("f8", "f4", "c16", "i4"))


@st.composite
def time_groups(draw: st.DrawFn) -> dict[str, Any]:
    """A ``/time`` group: outputs (maybe inputs) of drawn lengths, dtypes and values, and a
    drawn ``sample_rate`` attribute (``None``: absent)."""
    n_samples = draw(st.sampled_from([300, 64, 100, 0, 10]))
    n_out = draw(st.sampled_from([1, 2, 0]))
    time = {
        "outputs": draw(arrays((n_samples, n_out), ("f8", "f4", "i4", "c16", "str"))),
        "sample_rate": draw(st.sampled_from([1024.0, 100, 0.0, -5.0, np.nan, "fast",
                                             np.array([1.0, 2.0]), 1e-300, 1e300, None])),
    }
    if draw(st.booleans()):
        n_in = draw(st.sampled_from([n_samples, n_samples + 1]))
        time["inputs"] = draw(arrays((n_in, 1), ("f8", "f4")))
    if draw(st.integers(0, 12)) == 12:
        time["outputs"] = ("huge", (2**28, 1), "f8")
    return time


def write_hdf5(path: Path, layout: dict[str, Any]) -> None:
    """Write an HDF5 file with the content of a layout from :func:`hdf5_layouts`."""
    with h5py.File(path, "w") as f:
        for name, value in layout["datasets"].items():
            _put(f, name, value)
        for key, value in layout["attributes"].items():
            f.attrs[key] = value
        if layout["time"] is not None:
            time = f.create_group("time")
            for name, value in layout["time"].items():
                if name == "sample_rate":
                    if value is not None:
                        time.attrs["sample_rate"] = value
                else:
                    _put(time, name, value)


def _put(parent: h5py.Group, name: str, value: Any) -> None:
    """Create dataset (or group) ``name`` under ``parent`` unless an earlier one is in the
    way (a dataset where a group was asked for, or the reverse)."""
    try:
        if isinstance(value, str) and value == "group":
            parent.create_group(name)
        elif isinstance(value, tuple) and value[0] == "huge":
            parent.create_dataset(name, shape=value[1], dtype=value[2], chunks=True)
        else:
            parent.create_dataset(name, data=value)
    except (ValueError, TypeError, KeyError):
        pass  # the name is taken by a group or dataset of the other kind: keep that one


DAMAGES = ("truncate", "flip", "zero_tail", "append")
"""What may happen to a written file: cut short, bytes flipped, the end zeroed, garbage
appended."""


@st.composite
def damaged(draw: st.DrawFn, make: Callable[[Path], None]) -> Callable[[Path], None]:
    """A file maker that writes with ``make`` and then, in about one case of three, damages
    the bytes as drawn (:data:`DAMAGES`)."""
    damage = pick(draw, ["none"], list(DAMAGES), clean=False)
    where = draw(st.floats(0.0, 1.0))
    seed = draw(st.integers(0, 2**32 - 1))

    def write(path: Path) -> None:
        make(path)
        if damage == "none":
            return
        content = bytearray(path.read_bytes())
        cut = int(where * len(content))
        if damage == "truncate":
            content = content[:cut]
        elif damage == "flip":
            rng = np.random.default_rng(seed)
            for i in rng.integers(0, max(1, len(content)), size=8):
                if i < len(content):
                    content[i] ^= int(rng.integers(1, 256))
        elif damage == "zero_tail":
            content[cut:] = bytes(len(content) - cut)
        else:
            content += np.random.default_rng(seed).bytes(64)
        path.write_bytes(bytes(content))

    note(f"damage: {damage} at {where:.3f}")
    return write


@st.composite
def hdf5_inputs(draw: st.DrawFn, mode: str | None = None) -> Input:
    """An HDF5 input (FRF file, time series or junk) with a drawn suffix, maybe damaged
    (``mode`` as in :func:`hdf5_layouts`)."""
    layout = draw(hdf5_layouts(mode))
    note(f"layout: {_describe_layout(layout)}")
    suffix = pick(draw, [".h5", ".hdf5", ".H5"], ["", ".dat"], not layout["damage"])
    write = lambda path: write_hdf5(path, layout)  # noqa: E731
    return Input(suffix, draw(damaged(write)) if layout["damage"] else write)


def _describe_layout(layout: dict[str, Any]) -> str:
    """A short text of a layout for Hypothesis' notes."""

    def describe(value: Any) -> str:
        if isinstance(value, np.ndarray):
            return f"{value.dtype}{value.shape}"
        return repr(value)

    parts = [f"{k}={describe(v)}" for k, v in layout["datasets"].items()]
    parts += [f"@{k}={describe(v)}" for k, v in layout["attributes"].items()]
    if layout["time"]:
        parts += [f"time/{k}={describe(v)}" for k, v in layout["time"].items()]
    return ", ".join(parts)


JUNK = (b"", b"\x89HDF\r\n\x1a\n", b"\x89HDF\r\n\x1a\n" + bytes(600), b"frequency,frf\n1,2\n",
        b"PK\x03\x04" + bytes(40), b"\x93NUMPY" + bytes(20), b"    -1\n    58\n", b"\xff" * 100)
"""Byte strings that start like one format or another and are none of them."""


@st.composite
def junk_inputs(draw: st.DrawFn) -> Input:
    """A file of junk bytes (random, or a format's signature with nothing valid behind)."""
    content = draw(st.one_of(st.sampled_from(JUNK), st.binary(max_size=300)))
    suffix = draw(st.sampled_from([".h5", ".hdf5", ".uff", ".unv", ".csv", ".txt", ".npz",
                                   "", ".dat", ".npy", ".mat", ".tsv", ".tdms"]))
    return Input(suffix, lambda path: path.write_bytes(content))


CSV_TOKENS = ("1", "2.5", "-3e-3", "0", "1e308", "1e999", "-1e999", "nan", "NaN", "inf",
              "-inf", "", "abc", "1,5", "0x10", "1_000", "\u00e9", "1e-320", "+7", ".5", "5.",
              "1e", "--1")
"""Cells that a CSV reader meets: numbers, overflowing numbers, non-finite spellings, text."""


@st.composite
def csv_inputs(draw: st.DrawFn) -> Input:
    """A CSV or text table: mostly well formed (increasing frequencies, pairs of columns),
    with drawn oddities (bad cells, ragged rows, headers, quantity comments, encodings)."""
    faults = Faults(draw, ("shape", "frequency", "cells", "text"))
    n_rows = faults.pick(draw, "shape", [20, 5, 2, 1], [0])
    n_pairs = faults.pick(draw, "shape", [1, 2, 3], [0])
    n_cols = 1 + 2 * n_pairs + faults.pick(draw, "shape", [0], [1, -1])
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    sep = faults.pick(draw, "text", [",", ", ", " ", "\t", " , "], [";"])
    freq = np.asarray(draw(frequencies(n_rows, faults.clean("frequency")))).reshape(-1)
    rows = []
    for k in range(n_rows):
        f = freq[k] if freq.size > k else k
        cells = [str(f)] + [repr(float(x)) for x in rng.standard_normal(max(0, n_cols - 1))]
        rows.append(cells)
    for _ in range(0 if faults.clean("cells") else draw(st.integers(0, 2))):
        k = draw(st.integers(0, len(rows) - 1)) if rows else 0
        if rows and rows[k]:
            if draw(st.booleans()):
                cell = draw(st.integers(0, len(rows[k]) - 1))
                rows[k][cell] = draw(st.sampled_from(CSV_TOKENS))
            else:
                rows[k] = rows[k][:-1]  # a ragged row
    lines = [sep.join(r) for r in rows]
    if draw(st.booleans()):
        lines.insert(0, sep.join(["frequency"] + [f"y{i}_{p}" for i in range(n_pairs)
                                                  for p in ("re", "im")]))
    if draw(st.booleans()):
        lines.insert(0, "# quantity: " + faults.pick(draw, "text", list(QUANTITIES),
                                                     ["force", ""]))
    if draw(st.booleans()):
        lines.insert(draw(st.integers(0, len(lines))), draw(st.sampled_from(["", "#", "   "])))
    text = "\n".join(lines) + draw(st.sampled_from(["\n", "", "\r\n"]))
    encoding = faults.pick(draw, "text", ["utf-8", "utf-8-sig"], ["utf-16", "cp1252"])
    content = text.encode(encoding, errors="replace")
    return Input(draw(st.sampled_from([".csv", ".txt", ".CSV"])),
                 lambda path: path.write_bytes(content))


@st.composite
def npz_inputs(draw: st.DrawFn) -> Input:
    """An NPZ archive: drawn keys and arrays, sometimes compressed, sometimes damaged, with
    members that are not ``.npy`` or declare a huge array."""
    faults = Faults(draw, ("shape", "frequency", "frf", "quantity", "member", "damage"))
    n = faults.pick(draw, "shape", [10, 3, 1], [0])
    ny = faults.pick(draw, "shape", [2, 1], [0])
    shape = faults.pick(draw, "shape", [(n, ny, 1), (n, ny)], [(n,), (ny, n, 1), (n, ny, 1, 1)])
    content: dict[str, Any] = {}
    if faults.pick(draw, "frequency", [True], [False]):
        content["frequency"] = draw(frequencies(n, faults.clean("frequency")))
    if faults.pick(draw, "frf", [True], [False]):
        dtypes = ("c16", "c8", "clongdouble") + (() if faults.clean("frf") else ("f8", "i4"))
        specials = () if faults.clean("frf") else SPECIAL_VALUES
        content["frf"] = draw(arrays(shape, dtypes, specials))
    if draw(st.booleans()):
        content["quantity"] = np.array(faults.pick(draw, "quantity",
                                                   list(QUANTITIES) + [b"velocity"],
                                                   ["force", ["displacement"], 3, [b"\xff"]]))
    if draw(st.booleans()):
        content["extra"] = np.arange(3)
    if not faults.clean("frf") and draw(st.integers(0, 8)) == 8:
        content["frf"] = np.array([object()], dtype=object)  # pickled: must be refused
    member = faults.pick(draw, "member", ["npy"], ["raw", "huge_header"])
    if member != "npy":
        content = {k: v for k, v in content.items() if k not in ("frf", "frequency")}
    compressed = draw(st.booleans())

    def make(path: Path) -> None:
        buffer = io.BytesIO()
        (np.savez_compressed if compressed else np.savez)(buffer, **content)
        if member != "npy":
            with zipfile.ZipFile(buffer, "a") as z:
                if member == "raw":  # members named without .npy hold raw bytes
                    z.writestr("frf", b"not an array")
                    z.writestr("frequency", b"1 2 3")
                else:
                    z.writestr("frf.npy", _npy_header((10**12, 1, 1), "<c16") + bytes(64))
                    z.writestr("frequency.npy", _npy_header((3,), "<f8") + bytes(24))
        path.write_bytes(buffer.getvalue())

    return Input(".npz", make if faults.clean("damage") else draw(damaged(make)))


def _npy_header(shape: tuple[int, ...], descr: str) -> bytes:
    """The header of a ``.npy`` file declaring an array of ``shape`` and ``descr``."""
    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        buffer, {"descr": descr, "fortran_order": False, "shape": shape})
    return buffer.getvalue()


@st.composite
def uff_inputs(draw: st.DrawFn) -> Input:
    """A universal file of dataset-58 sets (valid FRFs, or other function types, real
    data, mismatched axes, duplicate or missing pairs), ASCII or binary, maybe damaged."""
    faults = Faults(draw, ("shape", "frequency", "values", "channels", "types", "damage"))
    n = faults.pick(draw, "shape", [20, 8, 2], [1])
    n_sets = draw(st.sampled_from([1, 2, 3]))
    binary = draw(st.sampled_from([0, 1]))
    sets = []
    for k in range(n_sets):
        axis = faults.pick(draw, "frequency", [np.arange(1.0, n + 1)], [draw(frequencies(n))])
        x = np.real(np.asarray(axis)).astype(float).reshape(-1)  # a UFF axis is real
        values = draw(arrays((x.size,), faults.pick(draw, "values", [("c16",)], [("f8",)]),
                             faults.pick(draw, "values", [()], [SPECIAL_VALUES])))
        ref = faults.pick(draw, "channels", [(1, 3)], [(k, 3)])
        rsp = (k + 1, faults.pick(draw, "channels", [3, -3, 1], [0, 7]))
        options = {"binary": binary, "func_type": faults.pick(draw, "types", [4], [1, 6]),
                   "abscissa_spacing": 1,
                   "abscissa_spec_data_type": faults.pick(draw, "types", [18], [17]),
                   "ordinate_spec_data_type": draw(st.sampled_from([12, 8, 11, 0])),
                   "orddenom_spec_data_type": faults.pick(draw, "types", [13], [12])}
        try:
            sets.append(pyuff.prepare_58(rsp_node=rsp[0], rsp_dir=rsp[1], ref_node=ref[0],
                                         ref_dir=ref[1], data=values, x=x, **options))
        except Exception:  # noqa: BLE001 - pyuff refuses some inputs itself; skip the set
            continue

    def make(path: Path) -> None:
        try:
            pyuff.UFF(str(path)).write_sets(sets, mode="add")
        except Exception:  # noqa: BLE001 - pyuff could not write these sets: a junk file
            path.write_bytes(b"    -1\n    58\n" + bytes(20))
        if not path.exists():
            path.write_bytes(b"")

    suffix = draw(st.sampled_from([".uff", ".unv"]))
    return Input(suffix, make if faults.clean("damage") else draw(damaged(make)))


@st.composite
def sample_inputs(draw: st.DrawFn) -> Input:
    """Time records without a sample rate of their own unless a time axis gives it: a
    ``.npy`` array (drawn shape, orientation, dtype and values, maybe a time row, uniform or
    with a gap), or a CSV table of samples with a time column, maybe damaged."""
    faults = Faults(draw, ("shape", "values", "time"))
    n = faults.pick(draw, "shape", [256, 100], [40, 3, 0])
    shape = faults.pick(draw, "shape", [(n, 2), (2, n), (n,)], [(3, 3), (n, 2, 1), ()])
    values = draw(arrays(shape, NUMERIC_DTYPES if not faults.clean("values") else ("f8", "f4"),
                         SPECIAL_VALUES if not faults.clean("values") else ()))
    time = faults.pick(draw, "time", ["none", "uniform"], ["gap", "constant"])
    if time != "none" and values.ndim == 2 and values.shape[0] != values.shape[1]:
        long = max(values.shape)
        t = np.arange(long) / 100.0
        if time == "gap":
            t[long // 2:] += 0.05
        elif time == "constant":
            t[:] = 1.0
        axis = 1 if values.shape[0] == long else 0
        values = np.concatenate([np.expand_dims(t, axis), values.real.astype(float)], axis=axis)
    if draw(st.booleans()) or values.ndim != 2 or values.dtype.kind not in "fiu":
        def make(path: Path) -> None:
            np.save(path, values)

        return Input(".npy", draw(damaged(make)))
    table = values if values.shape[0] > values.shape[1] else values.T
    header = ",".join(["t"] + [f"ch{i}" for i in range(1, table.shape[1])])
    text = header + "\n" + "\n".join(",".join(repr(float(v)) for v in row) for row in table)
    return Input(".csv", lambda path: path.write_text(text + "\n", encoding="utf-8"))


ANY_INPUT = st.one_of(hdf5_inputs(), hdf5_inputs(), csv_inputs(), npz_inputs(), uff_inputs(),
                      junk_inputs())
"""Every kind of input, HDF5 twice as often."""


# ---------------------------------------------------------------------------- checking


@contextmanager
def folder() -> Iterator[Path]:
    """A fresh temporary folder per example (pytest's ``tmp_path`` is per test)."""
    with tempfile.TemporaryDirectory(prefix="automodal-hyp-") as name:
        yield Path(name)


def read_checked(path: Path) -> FRFData | InputError:
    """Read ``path`` with :func:`read_any` (time series made FRFs by :func:`as_frfdata`, as
    the command line does) and check the outcome.

    The reader must return a valid :class:`FRFData` or raise :class:`InputError` with one
    line that names the file; any other exception propagates (and fails the test). The
    file's bytes and the folder's content must be unchanged.

    Returns
    -------
    FRFData or InputError
        What the reader returned, or the error it raised.
    """
    before = _snapshot(path.parent)
    try:
        outcome: FRFData | InputError = as_frfdata(read_any(path))
    except InputError as exc:
        message = str(exc)
        assert "\n" not in message and "\r" not in message, message
        assert message.startswith(f"{path}: "), message
        assert exc.problem, message
        event(f"refused: {' '.join(exc.problem.split()[:3])}")
        outcome = exc
    else:
        check_valid(outcome, path)
        event(f"read: {outcome.n_freq} lines")
    assert _snapshot(path.parent) == before, "the reader changed its folder"
    return outcome


def read_written(case: Input) -> FRFData | InputError:
    """Write ``case`` in a fresh folder and :func:`read_checked` it."""
    with folder() as where:
        return read_checked(case.write(where))


def _snapshot(where: Path) -> dict[str, bytes]:
    """Every file in ``where`` with its bytes."""
    return {p.name: p.read_bytes() for p in sorted(where.iterdir()) if p.is_file()}


def check_valid(data: FRFData, path: Path) -> None:
    """Assert that ``data`` keeps every rule of ``docs/frf-file.md``."""
    f, H = data.frequency, data.frf
    assert f.ndim == 1 and f.size >= 1 and f.dtype == np.float64
    assert np.all(np.isfinite(f)) and f[0] >= 0 and np.all(np.diff(f) > 0)
    assert H.ndim == 3 and H.shape[0] == f.size and H.size > 0
    assert H.dtype == np.complex128 and np.all(np.isfinite(H))
    assert data.quantity in QUANTITIES
    assert len(data.output_names) == data.n_outputs
    assert len(data.input_names) == data.n_inputs
    assert all(isinstance(s, str) for s in data.output_names + data.input_names)
    if data.coherence is not None:
        assert data.coherence.shape == H.shape
        assert np.all((data.coherence >= 0) & (data.coherence <= 1))
    if data.records is not None:
        assert data.records.shape[1:] == H.shape and np.all(np.isfinite(data.records))
    for nodes, n in ((data.output_nodes, data.n_outputs), (data.input_nodes, data.n_inputs)):
        assert nodes is None or (nodes.shape == (n,) and nodes.dtype.kind == "i")
    if data.output_xyz is not None:
        assert data.output_xyz.shape == (data.n_outputs, 3)
    decay = data.attributes.get("window_decay_per_s")
    if decay is not None:  # None (an empty attribute) is taken as 0 by the pipeline
        assert isinstance(decay, (int, float)) and not isinstance(decay, bool)
        assert np.isfinite(decay) and decay >= 0
    assert data.source == str(path)


# ------------------------------------------------------------------------------- tests


@given(hdf5_inputs())
@settings(_BASE)
def test_hdf5_inputs_read_or_are_refused_in_one_line(case: Input) -> None:
    """HDF5 files of drawn layouts, dtypes, values and attributes, maybe damaged."""
    read_written(case)


@given(csv_inputs())
@settings(_BASE)
def test_csv_inputs_read_or_are_refused_in_one_line(case: Input) -> None:
    """CSV and text tables with bad cells, ragged rows, headers, comments, encodings."""
    read_written(case)


@given(npz_inputs())
@settings(_BASE)
# numpy says so when the test writes a drawn array whose dtype carries metadata
@pytest.mark.filterwarnings("ignore:metadata on a dtype is not saved:UserWarning")
def test_npz_inputs_read_or_are_refused_in_one_line(case: Input) -> None:
    """NPZ archives with drawn keys and arrays, raw members, huge headers, damage."""
    read_written(case)


@given(uff_inputs())
@examples(0.5)
def test_uff_inputs_read_or_are_refused_in_one_line(case: Input) -> None:
    """Universal files of drawn dataset-58 sets, maybe damaged."""
    read_written(case)


@given(sample_inputs())
@examples(0.5)
def test_sample_inputs_read_or_are_refused_in_one_line(case: Input) -> None:
    """Arrays and tables of samples: orientations, dtypes, special values, time axes."""
    read_written(case)


@given(junk_inputs())
@settings(_BASE)
def test_junk_is_refused_in_one_line(case: Input) -> None:
    """Random bytes and formats' signatures with nothing behind, under every suffix."""
    assert isinstance(read_written(case), InputError)


@given(hdf5_inputs(mode="clean"))
@examples(0.3)
def test_valid_files_are_identified_or_refused_in_one_line(case: Input) -> None:
    """A file that keeps the spec (with awkward content: dead or identical channels, a 0 Hz
    line, extreme magnitudes, one line, pure noise) reads; the pipeline then identifies it,
    with reports that can be written, or refuses it in one line: nothing else."""
    from automodal.io.report import report_dict, save_report
    from automodal.pipeline import identify
    from automodal.settings import Settings

    with folder() as where:
        path = case.write(where)
        data = read_checked(path)
        assert isinstance(data, FRFData), data
        try:
            result = identify(data, Settings(n_bootstrap=4, jobs=1))
        except InputError as exc:
            assert "\n" not in str(exc), str(exc)
            event(f"identify refused: {' '.join(exc.problem.split()[:4])}")
            return
        event(f"identified: {len(result.physical_modes)} physical modes")
        report = report_dict(result, data, input_path=path)
        save_report(where / "r.json", report)
        save_report(where / "r.h5", report, result.poles, frf=result.frf_fit)
        assert json.loads((where / "r.json").read_text(encoding="utf-8"))["modes"] == \
            report["modes"]


def run_identify(path: Path, report: Path) -> subprocess.CompletedProcess[str]:
    """``python -m automodal identify PATH -o REPORT`` (small bootstrap, one process)."""
    command = [sys.executable, "-m", "automodal", "identify", str(path), "-o", str(report),
               "--bootstrap", "4", "--jobs", "1", "--quiet"]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    return subprocess.run(command, capture_output=True, text=True, timeout=300, env=env)


@given(ANY_INPUT)
@examples(0.15)
def test_cli_refuses_in_one_line_and_writes_no_report(case: Input) -> None:
    """The CLI agrees with the reader: a refused input exits 2 with one line on stderr and
    writes nothing; an input that reads gives a complete report (or a one-line refusal,
    e.g. too few lines for the identification)."""
    with folder() as where:
        path = case.write(where)
        outcome = read_checked(path)
        report = where / "r.json"
        done = run_identify(path, report)
        note(f"exit {done.returncode}; stderr: {done.stderr!r}")
        assert "Traceback" not in done.stderr
        left = sorted(p.name for p in where.iterdir() if p.name not in (path.name, "r.json"))
        assert left == [], left  # no temporary file left behind
        if isinstance(outcome, InputError) or done.returncode != 0:
            assert done.returncode == 2, done.stderr
            lines = done.stderr.splitlines()
            assert len(lines) == 1 and lines[0].startswith("automodal: error: "), lines
            assert str(path) in lines[0] or path.name in lines[0]
            assert not report.exists()
        if isinstance(outcome, InputError):
            assert lines[0] == f"automodal: error: {outcome}"
        if done.returncode == 0:
            content = json.loads(report.read_text(encoding="utf-8"))
            assert content["format"] == "automodal-report"
            assert done.stdout == ""
