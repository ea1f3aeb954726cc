"""FRFData and TimeSeries check themselves: one test per rule, one message per problem; and
the pipeline's input stage (``as_frfdata``) that turns time series into FRFs."""

from __future__ import annotations

import dataclasses

import h5py
import numpy as np
import pytest

from automodal.core.from_time import as_frfdata
from automodal.errors import InputError
from automodal.frfdata import QUANTITIES, FRFData, quantity_problem
from automodal.io.readers import read_any
from automodal.io.time_file import write_time
from automodal.timedata import TimeSeries

N_FREQ, N_OUT, N_IN, N_REC = 6, 2, 3, 4
SOURCE = "test.h5"


def arrays(seed: int = 0) -> dict:
    """The fields of a valid test with every optional array."""
    rng = np.random.default_rng(seed)
    shape = (N_FREQ, N_OUT, N_IN)
    frf = rng.standard_normal(shape) + 1j * rng.standard_normal(shape)
    return {
        "frequency": np.linspace(0.0, 50.0, N_FREQ),
        "frf": frf,
        "coherence": rng.uniform(0.0, 1.0, shape),
        "records": frf + 0.1 * rng.standard_normal((N_REC,) + shape),  # measurements of it
        "output_names": ["a", "b"],
        "input_names": ["u", "v", "w"],
        "output_nodes": np.array([1, 2]),
        "input_nodes": np.array([3, 4, 5]),
        "output_directions": ["+X", "+Y"],
        "input_directions": ["+Z", "+Z", "-Z"],
        "output_xyz": np.zeros((N_OUT, 3)),
        "quantity": "velocity",
        "source": SOURCE,
    }


def refused(*fragments: str, **changes) -> str:
    """Make an FRFData with ``changes``; expect one InputError line naming the source and
    holding every fragment."""
    with pytest.raises(InputError) as info:
        FRFData(**{**arrays(), **changes})
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"{SOURCE}: "), message
    for fragment in fragments:
        assert fragment in info.value.problem, message
    return info.value.problem


def test_a_valid_test_is_accepted_and_converted():
    data = FRFData(**{**arrays(), "frequency": [0, 1, 2, 3, 4, 5]})
    assert data.frequency.dtype == np.float64 and data.frf.dtype == np.complex128
    assert (data.n_freq, data.n_outputs, data.n_inputs) == (N_FREQ, N_OUT, N_IN)
    data.validate()


def test_default_names_one_per_channel():
    data = FRFData(frequency=arrays()["frequency"], frf=arrays()["frf"])
    assert data.output_names == ["y1", "y2"] and data.input_names == ["u1", "u2", "u3"]
    assert data.quantity == "displacement" and data.source is None


def test_a_real_frf_array_is_made_complex():
    data = FRFData(frequency=arrays()["frequency"], frf=arrays()["frf"].real)
    assert data.frf.dtype == np.complex128


# ------------------------------------------------------------------------ shape rules


@pytest.mark.parametrize("frequency", [np.zeros((2, 3)), np.zeros(0)], ids=["2-D", "empty"])
def test_frequency_must_be_1d_and_not_empty(frequency):
    refused("frequency axis must be 1-D and not empty", frequency=frequency)


@pytest.mark.parametrize("frf", [np.ones((N_FREQ, N_OUT)), np.ones((N_FREQ - 1, N_OUT, N_IN))],
                         ids=["2-D", "lines"])
def test_frf_must_be_3d_with_one_line_per_frequency(frf):
    refused("the FRF array has shape", f"expected ({N_FREQ}, n_outputs, n_inputs)", frf=frf,
            coherence=None, records=None)


def test_frf_must_not_be_empty():
    refused("the FRF array is empty", frf=np.ones((N_FREQ, 0, N_IN)), coherence=None,
            records=None, output_names=[], output_nodes=None, output_directions=None,
            output_xyz=None)


def test_frf_must_hold_numbers():
    refused("the FRFs must hold numbers", frf=np.full((N_FREQ, N_OUT, N_IN), "x"))


def test_coherence_must_have_the_frf_shape():
    refused("the coherence has shape", coherence=np.ones((N_FREQ, N_OUT)))


@pytest.mark.parametrize("records", [np.ones((N_FREQ, N_OUT, N_IN)) + 1j,
                                     np.ones((N_REC, N_FREQ, N_OUT, 1)) + 1j,
                                     np.ones((0, N_FREQ, N_OUT, N_IN)) + 1j],
                         ids=["3-D", "shape", "none"])
def test_records_must_have_a_first_axis_more_than_the_frf(records):
    refused("the repeated records have shape", records=records)


# ------------------------------------------------------------------------ value rules


@pytest.mark.parametrize("value", [np.nan, np.inf])
def test_frequency_must_be_finite(value):
    frequency = arrays()["frequency"]
    frequency[3] = value
    refused("frequency axis has 1 non-finite value(s)", frequency=frequency)


def test_frequency_must_not_be_negative():
    refused("negative values (first line -5 Hz)", frequency=arrays()["frequency"] - 5.0)


@pytest.mark.parametrize("index", [2, 5])
def test_frequency_must_increase_strictly(index):
    frequency = arrays()["frequency"]
    frequency[index] = frequency[index - 1]
    assert refused("not strictly increasing", frequency=frequency).startswith(
        f"the frequencies are not strictly increasing (line {index}:")


@pytest.mark.parametrize("value", [complex(np.nan, 0), complex(1, np.inf)])
def test_frf_must_be_finite(value):
    frf = arrays()["frf"]
    frf[1, 1, 2] = value
    refused("the FRFs have 1 non-finite value(s)", frf=frf)


def test_records_must_be_finite():
    records = arrays()["records"]
    records[0, 0, 0, 0] = np.nan
    refused("the repeated records have 1 non-finite value(s)", records=records)


@pytest.mark.parametrize("value", [-0.1, 1.5, np.nan])
def test_coherence_must_be_in_0_1(value):
    coherence = arrays()["coherence"]
    coherence[2, 0, 1] = value
    refused("coherence has values outside [0, 1]", coherence=coherence)


@pytest.mark.parametrize("field, value", [("output_names", ["a"]),
                                          ("input_names", ["a", "b", "c", "d"])])
def test_one_name_per_channel(field, value):
    side = field.split("_")[0]
    refused(f"{len(value)} {side} names for", **{field: value})


@pytest.mark.parametrize("field, value", [("output_nodes", np.arange(3)),
                                          ("input_nodes", np.arange(6).reshape(3, 2)),
                                          ("output_directions", ["+X"]),
                                          ("input_directions", ["+X"] * 4)])
def test_one_node_and_direction_per_channel(field, value):
    side, what = field.split("_")
    refused(f"{side} {what} for", "one per channel", **{field: value})


def test_output_coordinates_are_n_outputs_by_3():
    refused("output coordinates have shape (2, 2), expected (2, 3)",
            output_xyz=np.zeros((N_OUT, 2)))


def test_quantity_must_be_known():
    problem = refused("unknown quantity 'force'", quantity="force")
    assert problem == quantity_problem("force")
    assert all(quantity_problem(q) is None for q in QUANTITIES)


def test_validate_sees_arrays_changed_in_place_and_replace_checks_too():
    data = FRFData(**arrays())
    data.frf[0, 0, 0] = np.nan
    with pytest.raises(InputError, match="the FRFs have 1 non-finite"):
        data.validate()
    data.frf[0, 0, 0] = 1.0
    with pytest.raises(InputError, match="the coherence has shape"):
        dataclasses.replace(data, frf=data.frf[:, :1], output_names=["a"],
                            output_nodes=None, output_directions=None, output_xyz=None)


def test_the_pipeline_refuses_data_changed_in_place():
    from automodal.pipeline import identify
    from automodal.settings import Settings

    data = FRFData(**arrays())
    data.frequency[4] = data.frequency[3]
    with pytest.raises(InputError, match="not strictly increasing"):
        identify(data, Settings(n_bootstrap=2, jobs=1))


# ------------------------------------------------------------------------ TimeSeries


def series(**changes) -> TimeSeries:
    rng = np.random.default_rng(3)
    fields = {"outputs": rng.standard_normal((256, 2)), "inputs": rng.standard_normal(256),
              "sample_rate": 128.0, "source": SOURCE, **changes}
    return TimeSeries(**fields)


def test_time_series_valid_and_one_channel_from_1d():
    ts = series()
    assert ts.inputs.shape == (256, 1) and ts.input_names == ["u1"]


@pytest.mark.parametrize("changes, fragment", [
    ({"outputs": np.zeros((2, 2, 2))}, "must be (n_samples, n_channels)"),
    ({"outputs": np.zeros((0, 2))}, "no sample or no channel"),
    ({"outputs": np.full((256, 2), np.nan)}, "the outputs have 512 non-finite"),
    ({"inputs": np.full(256, np.inf)}, "the inputs have 256 non-finite"),
    ({"inputs": np.ones(100)}, "the inputs have 100 samples but the outputs 256"),
    ({"sample_rate": 0.0}, "sample_rate must be a finite number > 0"),
    ({"sample_rate": "fast"}, "sample_rate must be a finite number > 0"),
    ({"output_names": ["a"]}, "1 output names for 2 output channels"),
    ({"outputs": np.full((256, 2), "x")}, "the outputs must hold real numbers"),
], ids=["3-D", "empty", "nan", "inf", "lengths", "rate", "rate-text", "names", "text"])
def test_time_series_rules(changes, fragment):
    with pytest.raises(InputError) as info:
        series(**changes)
    assert fragment in info.value.problem and str(info.value).startswith(f"{SOURCE}: ")


# ------------------------------------------------------------------------ as_frfdata


def test_as_frfdata_returns_frfdata_unchanged():
    data = FRFData(**arrays())
    assert as_frfdata(data) is data
    with pytest.raises(TypeError):
        as_frfdata(np.zeros(3))


def test_read_any_gives_time_series_and_as_frfdata_makes_frfs(tmp_path):
    rng = np.random.default_rng(5)
    path = tmp_path / "t.h5"
    write_time(path, TimeSeries(rng.standard_normal((2048, 2)), None, 256.0,
                                attributes={"quantity": "acceleration"}))
    ts = read_any(path)
    assert isinstance(ts, TimeSeries) and ts.source == str(path)
    data = as_frfdata(ts)
    assert isinstance(data, FRFData) and data.source == str(path)
    assert data.quantity == "acceleration" and data.attributes["analysis"] == "operational"
    info = data.attributes["time_analysis"]
    assert data.attributes["window_decay_per_s"] == info["lag_window_decay_per_s"] > 0


def test_as_frfdata_refusal_names_the_source(tmp_path):
    path = tmp_path / "dead.h5"
    outputs = np.random.default_rng(6).standard_normal((512, 2))
    write_time(path, TimeSeries(outputs, None, 100.0))
    with h5py.File(path, "r+") as f:
        f.attrs["quantity"] = "velocity"
    ts = read_any(path)
    ts.outputs[:, 1] = 0.5  # dead channel, made after reading
    with pytest.raises(InputError) as info:
        as_frfdata(ts)
    assert str(info.value).startswith(f"{path}: ") and "constant" in str(info.value)
