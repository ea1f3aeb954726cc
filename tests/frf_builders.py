"""Small FRF files for tests, written with h5py directly (independent of ``write_frf``).

``write_valid`` writes a valid file with every optional field and lets a test change one thing
before the file is closed; ``BAD_CASES`` lists malformed inputs that a reader must refuse.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import h5py
import numpy as np

N_FREQ, N_OUT, N_IN, N_REC = 8, 3, 2, 4

Mutation = Callable[[h5py.File], None]


def valid_content(seed: int = 0) -> dict[str, Any]:
    """The arrays and metadata of the valid test file, by HDF5 name."""
    rng = np.random.default_rng(seed)
    shape = (N_FREQ, N_OUT, N_IN)
    frf = rng.standard_normal(shape) + 1j * rng.standard_normal(shape)
    return {
        "frequency": np.linspace(0.0, 70.0, N_FREQ),
        "frf": frf,
        "coherence": rng.uniform(0.0, 1.0, shape),
        # measurements of the FRF: it plus noise
        "records/frf": frf + 0.1 * (rng.standard_normal((N_REC,) + shape)
                                    + 1j * rng.standard_normal((N_REC,) + shape)),
        "outputs/name": ["tip", "middle", "root"],
        "outputs/node": np.array([3, 2, 1]),
        "outputs/direction": ["+Z", "+Z", "-Y"],
        "outputs/xyz": rng.standard_normal((N_OUT, 3)),
        "inputs/name": ["hammer", "shaker"],
        "inputs/node": np.array([3, 1]),
        "inputs/direction": ["-Z", "+Y"],
    }


VALID_ATTRIBUTES = {
    "format": "automodal-frf",
    "version": 1,
    "quantity": "acceleration",
    "structure": "cantilever beam",
    "date": "2024-05-01T10:30:00",
    "temperature": 21.5,
}
"""Root attributes of the valid test file."""


def write_valid(path: Path, mutate: Mutation | None = None) -> Path:
    """Write the valid test file at ``path``; ``mutate(f)`` may change it before closing."""
    with h5py.File(path, "w") as f:
        for name, value in valid_content().items():
            f.create_dataset(name, data=_storable(value))
        f.attrs.update(VALID_ATTRIBUTES)
        if mutate is not None:
            mutate(f)
    return path


def _storable(value: Any) -> Any:
    """A list of str as an HDF5 string array; anything else unchanged."""
    if isinstance(value, list):
        return np.array(value, dtype=h5py.string_dtype())
    return value


# ------------------------------------------------------------------------ mutations


def replace(name: str, value: Any) -> Mutation:
    """A mutation that replaces dataset ``name`` by ``value``."""

    def mutate(f: h5py.File) -> None:
        del f[name]
        f[name] = _storable(value)

    return mutate


def delete(*names: str) -> Mutation:
    """A mutation that deletes datasets or groups."""

    def mutate(f: h5py.File) -> None:
        for name in names:
            del f[name]

    return mutate


def set_attribute(key: str, value: Any) -> Mutation:
    """A mutation that sets a root attribute."""

    def mutate(f: h5py.File) -> None:
        f.attrs[key] = value

    return mutate


def combine(*mutations: Mutation) -> Mutation:
    """A mutation that applies several in turn."""

    def mutate(f: h5py.File) -> None:
        for m in mutations:
            m(f)

    return mutate


def frequency_with(index: int, value: float) -> Mutation:
    """A mutation that sets one frequency line."""
    freq = valid_content()["frequency"].copy()
    freq[index] = value
    return replace("frequency", freq)


def frf_with(value: complex) -> Mutation:
    """A mutation that sets one FRF value."""
    frf = valid_content()["frf"].copy()
    frf[2, 1, 0] = value
    return replace("frf", frf)


def coherence_with(value: float) -> Mutation:
    """A mutation that sets one coherence value."""
    coherence = valid_content()["coherence"].copy()
    coherence[5, 0, 1] = value
    return replace("coherence", coherence)


def add_time_series(f: h5py.File) -> None:
    """Give the file a ``/time`` group of raw time series."""
    group = f.create_group("time")
    group.attrs["sample_rate"] = 1024.0
    group["outputs"] = np.zeros((256, N_OUT))
    group["inputs"] = np.zeros((256, N_IN))


def frf_as_group(f: h5py.File) -> None:
    """Replace the ``/frf`` dataset by a group of the same name."""
    del f["frf"]
    f.create_group("frf")


# ---------------------------------------------------------------------- bad files


def mutated(mutate: Mutation) -> Callable[[Path], None]:
    """A file maker: the valid file with one mutation."""
    return lambda path: write_valid(path, mutate)


def raw_bytes(content: bytes) -> Callable[[Path], None]:
    """A file maker: a file with exactly these bytes."""
    return lambda path: path.write_bytes(content)


def truncated(path: Path) -> None:
    """A file maker: the valid file cut to half its size."""
    write_valid(path)
    content = path.read_bytes()
    path.write_bytes(content[: len(content) // 2])


@dataclass(frozen=True)
class BadCase:
    """A malformed input: how to make it, and a fragment the refusal must contain."""

    id: str
    make: Callable[[Path], None]
    fragment: str
    cli: bool = True  # False where the CLI may legitimately accept the path (a folder)


def bad(case_id: str, mutation: Mutation, fragment: str) -> BadCase:
    """A bad case: the valid file with one mutation."""
    return BadCase(case_id, mutated(mutation), fragment)


_FREQ = valid_content()["frequency"]
_FRF = valid_content()["frf"]
_EMPTY = combine(
    replace("frf", _FRF[:0]), replace("frequency", _FREQ[:0]), delete("coherence", "records")
)

BAD_CASES = [
    BadCase("missing", lambda path: None, "no such file"),
    BadCase("folder", lambda path: path.mkdir(), "folder", cli=False),
    BadCase("empty_file", raw_bytes(b""), "empty"),
    BadCase("not_hdf5", raw_bytes(b"frequency,frf\n1.0,2.0\n"), "not an HDF5 file"),
    BadCase("truncated", truncated, "truncated"),
    bad("no_frf_no_time", delete("frf"), "no /frf"),
    bad("time_only", combine(delete("frf"), add_time_series), "not supported"),
    bad("frf_is_group", frf_as_group, "must be a dataset"),
    bad("frequency_missing", delete("frequency"), "no /frequency"),
    bad("frequency_too_short", replace("frequency", _FREQ[:-1]), "first axis"),
    bad("frequency_too_long", replace("frequency", np.append(_FREQ, 80.0)), "first axis"),
    bad("frequency_2d", replace("frequency", _FREQ.reshape(2, -1)), "1-D"),
    bad("frf_2d", replace("frf", _FRF[:, :, 0]), "3-D"),
    bad("frf_4d", replace("frf", _FRF[None]), "3-D"),
    bad("frf_real", replace("frf", _FRF.real), "not complex"),
    bad("frequency_nan", frequency_with(3, np.nan), "non-finite"),
    bad("frequency_inf", frequency_with(7, np.inf), "non-finite"),
    bad("frf_nan", frf_with(complex(np.nan, 0.0)), "non-finite"),
    bad("frf_inf", frf_with(complex(1.0, np.inf)), "non-finite"),
    bad("frequency_repeated", frequency_with(4, _FREQ[3]), "strictly increasing"),
    bad("frequency_decreasing", replace("frequency", _FREQ[::-1].copy()), "strictly increasing"),
    bad("frequency_negative", replace("frequency", _FREQ - 5.0), "negative"),
    bad("quantity_unknown", set_attribute("quantity", "force"), "unknown quantity"),
    bad("version_newer", set_attribute("version", 2), "newer"),
    bad("version_not_integer", set_attribute("version", "one"), "integer"),
    bad("format_other", set_attribute("format", "other-frf"), "format"),
    bad("arrays_empty", _EMPTY, "empty"),
    bad("coherence_shape", replace("coherence", np.ones((N_FREQ, N_OUT))), "/coherence"),
    bad("coherence_above_one", coherence_with(1.5), "[0, 1]"),
    bad("coherence_negative", coherence_with(-0.1), "[0, 1]"),
    bad("coherence_nan", coherence_with(np.nan), "[0, 1]"),
    bad("records_shape", replace("records/frf", _FRF[None, :-1]), "/records/frf"),
    bad("records_real", replace("records/frf", _FRF.real[None]), "not complex"),
    bad("output_names_length", replace("outputs/name", ["a", "b"]), "/outputs/name"),
    bad("input_names_length", replace("inputs/name", ["a", "b", "c"]), "/inputs/name"),
    bad("output_nodes_length", replace("outputs/node", np.arange(4)), "/outputs/node"),
    bad("input_directions_length", replace("inputs/direction", ["+X"]), "/inputs/direction"),
    bad("names_not_strings", replace("outputs/name", np.arange(N_OUT)), "strings"),
    bad("nodes_not_integers", replace("inputs/node", np.array([1.5, 2.5])), "integers"),
    bad("xyz_shape", replace("outputs/xyz", np.zeros((N_OUT, 2))), "/outputs/xyz"),
    bad("xyz_nan", replace("outputs/xyz", np.full((N_OUT, 3), np.nan)), "coordinates"),
    bad("coherence_zero", replace("coherence", np.zeros((N_FREQ, N_OUT, N_IN))),
        "0 at every line"),
    bad("records_scaled", replace("records/frf", 10.0 * np.stack([_FRF] * N_REC)),
        "not its measurements"),
    bad("records_conjugate", replace("records/frf", np.conj(np.stack([_FRF] * N_REC))),
        "not its measurements"),
]
"""Every malformed input a reader must refuse."""
