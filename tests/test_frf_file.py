"""Reading and writing the automodal FRF file (docs/frf-file.md)."""

from __future__ import annotations

import hashlib
from pathlib import Path

import h5py
import numpy as np
import pytest
from frf_builders import BAD_CASES, N_IN, N_OUT, VALID_ATTRIBUTES, valid_content, write_valid

from automodal.errors import InputError
from automodal.frfdata import FRFData
from automodal.io.frf_file import read_frf, write_frf

# ---------------------------------------------------------------------------- helpers


def full_data(seed: int = 1) -> FRFData:
    """An FRFData with every optional field set."""
    rng = np.random.default_rng(seed)
    shape = (12, 2, 3)
    frf = rng.standard_normal(shape) + 1j * rng.standard_normal(shape)
    return FRFData(
        frequency=np.linspace(1.0, 100.0, shape[0]),
        frf=frf,
        quantity="velocity",
        coherence=rng.uniform(0.0, 1.0, shape),
        records=frf + 0.1 * (rng.standard_normal((5,) + shape)
                             + 1j * rng.standard_normal((5,) + shape)),
        output_names=["a1", "a2 (ü)"],
        input_names=["f1", "f2", "f3"],
        output_nodes=np.array([10, 20]),
        input_nodes=np.array([10, 20, 30]),
        output_directions=["+X", "-Z"],
        input_directions=["+X", "+Y", "+Z"],
        output_xyz=rng.standard_normal((2, 3)),
        attributes={
            "structure": "bridge deck",
            "date": "2024-05-01",
            "operator": "M. Curie",
            "temperature": 18.25,
            "runs": 3,
            "calibrated": True,
            "tags": ["ambient", "night"],
            "levels": [0.5, 1.0, 2.0],
        },
    )


def minimal_data() -> FRFData:
    """An FRFData with only the required fields."""
    frf = np.arange(10, dtype=float).reshape(5, 2, 1) * (1 - 2j)
    return FRFData(frequency=np.arange(5.0), frf=frf)


ARRAY_FIELDS = (
    "frequency",
    "frf",
    "coherence",
    "records",
    "output_nodes",
    "input_nodes",
    "output_xyz",
)
PLAIN_FIELDS = (
    "quantity",
    "output_names",
    "input_names",
    "output_directions",
    "input_directions",
    "attributes",
)


def assert_same(read: FRFData, written: FRFData) -> None:
    """Every field of ``read`` equals that of ``written`` exactly (source apart)."""
    for name in ARRAY_FIELDS:
        a, b = getattr(read, name), getattr(written, name)
        assert (a is None) == (b is None), name
        if a is not None:
            np.testing.assert_array_equal(a, b, err_msg=name)
            assert a.dtype.kind == np.asarray(b).dtype.kind, name
    for name in PLAIN_FIELDS:
        assert getattr(read, name) == getattr(written, name), name


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


# ------------------------------------------------------------------------- round trip


def test_round_trip_with_all_optional_fields(tmp_path):
    data = full_data()
    path = tmp_path / "full.h5"
    write_frf(path, data)
    back = read_frf(path)
    assert_same(back, data)
    assert back.source == str(path)
    assert type(back.attributes["runs"]) is int
    assert type(back.attributes["calibrated"]) is bool
    assert type(back.attributes["temperature"]) is float


def test_round_trip_with_required_fields_only(tmp_path):
    data = minimal_data()
    path = tmp_path / "minimal.h5"
    write_frf(path, data)
    back = read_frf(str(path))
    assert_same(back, data)
    assert back.output_names == ["y1", "y2"] and back.input_names == ["u1"]
    assert back.attributes == {}


def test_written_file_has_format_attributes(tmp_path):
    path = tmp_path / "x.h5"
    write_frf(path, minimal_data())
    with h5py.File(path, "r") as f:
        assert f.attrs["format"] == "automodal-frf"
        assert f.attrs["version"] == 1
        assert f.attrs["quantity"] == "displacement"


def test_write_skips_reserved_attribute_names(tmp_path):
    data = minimal_data()
    data.attributes = {"format": "other", "version": 9, "quantity": "x", "site": "lab"}
    path = tmp_path / "x.h5"
    write_frf(path, data)
    back = read_frf(path)
    assert back.attributes == {"site": "lab"}
    assert back.quantity == "displacement"


def test_write_replaces_existing_file_and_leaves_no_temporary(tmp_path):
    path = tmp_path / "x.h5"
    path.write_text("old")
    write_frf(path, full_data())
    assert read_frf(path).n_freq == 12
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.h5"]


def test_failed_write_leaves_existing_file_untouched(tmp_path):
    path = tmp_path / "x.h5"
    write_frf(path, minimal_data())
    before = sha256(path)
    data = full_data()
    data.attributes["nested"] = {"not": "storable"}
    with pytest.raises(TypeError):
        write_frf(path, data)
    assert sha256(path) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.h5"]


def test_write_refuses_unknown_quantity(tmp_path):
    data = minimal_data()
    data.quantity = "force"
    with pytest.raises(ValueError, match="quantity"):
        write_frf(tmp_path / "x.h5", data)
    assert not (tmp_path / "x.h5").exists()


# --------------------------------------------------------------------------- reading


def test_read_file_written_by_another_tool(tmp_path):
    path = write_valid(tmp_path / "valid.h5")
    data = read_frf(path)
    content = valid_content()
    np.testing.assert_array_equal(data.frequency, content["frequency"])
    np.testing.assert_array_equal(data.frf, content["frf"])
    np.testing.assert_array_equal(data.coherence, content["coherence"])
    np.testing.assert_array_equal(data.records, content["records/frf"])
    np.testing.assert_array_equal(data.output_xyz, content["outputs/xyz"])
    np.testing.assert_array_equal(data.output_nodes, content["outputs/node"])
    np.testing.assert_array_equal(data.input_nodes, content["inputs/node"])
    assert data.output_names == content["outputs/name"]
    assert data.input_names == content["inputs/name"]
    assert data.output_directions == content["outputs/direction"]
    assert data.input_directions == content["inputs/direction"]
    assert data.quantity == "acceleration"
    assert (data.n_outputs, data.n_inputs) == (N_OUT, N_IN)
    free = {k: v for k, v in VALID_ATTRIBUTES.items() if k not in ("format", "version", "quantity")}
    assert data.attributes == free


def test_read_accepts_missing_format_version_and_quantity(tmp_path):
    def strip(f):
        for key in ("format", "version", "quantity"):
            del f.attrs[key]

    data = read_frf(write_valid(tmp_path / "bare.h5", strip))
    assert data.quantity == "displacement"
    # the report's input attributes say it was assumed (docs/frf-file.md)
    assert "assumed displacement" in data.attributes["quantity_source"]
    assert "quantity_source" not in read_frf(write_valid(tmp_path / "full.h5")).attributes


def test_read_accepts_complex64_and_fixed_length_strings(tmp_path):
    def narrow(f):
        frf = f["frf"][()].astype(np.complex64)
        del f["frf"], f["outputs/name"]
        f["frf"] = frf
        f["outputs/name"] = np.array([b"p", b"q", b"r"], dtype="S1")

    data = read_frf(write_valid(tmp_path / "narrow.h5", narrow))
    assert data.frf.dtype == np.complex128
    assert data.output_names == ["p", "q", "r"]


def test_read_accepts_version_written_as_double(tmp_path):
    data = read_frf(write_valid(tmp_path / "v.h5", lambda f: f.attrs.__setitem__("version", 1.0)))
    assert data.n_freq == 8


def test_read_does_not_modify_the_file(tmp_path):
    path = write_valid(tmp_path / "valid.h5")
    before, mtime = sha256(path), path.stat().st_mtime_ns
    read_frf(path)
    assert sha256(path) == before
    assert path.stat().st_mtime_ns == mtime


@pytest.mark.parametrize("case", BAD_CASES, ids=[case.id for case in BAD_CASES])
def test_read_refuses(tmp_path, case):
    path = tmp_path / f"{case.id}.h5"
    case.make(path)
    with pytest.raises(InputError) as info:
        read_frf(path)
    message = str(info.value)
    assert "\n" not in message
    assert str(path) in message
    assert message.startswith(f"{path}: ")
    assert case.fragment in info.value.problem
    assert "Traceback" not in message


def test_unexpected_error_on_open_becomes_input_error(tmp_path, monkeypatch):
    path = write_valid(tmp_path / "valid.h5")

    def fail(*args, **kwargs):
        raise OSError("disk said no\nsecond line")

    monkeypatch.setattr(h5py, "File", fail)
    with pytest.raises(InputError) as info:
        read_frf(path)
    assert str(path) in str(info.value)
    assert "\n" not in str(info.value)


def test_unexpected_error_while_reading_becomes_input_error(tmp_path, monkeypatch):
    path = write_valid(tmp_path / "valid.h5")

    def fail(self, *args, **kwargs):
        raise RuntimeError("read failed\n(errno 5)")

    monkeypatch.setattr(h5py.Dataset, "__getitem__", fail)
    with pytest.raises(InputError) as info:
        read_frf(path)
    message = str(info.value)
    assert str(path) in message
    assert "read failed" in message
    assert "\n" not in message
