"""Simulated time tests (``automodal/core/simulate_time.py``, ``automodal simulate
--excitation``) and the truth tests of the three time routes of the input stage.

Truth tests: simulate -> :func:`automodal.identify` (its input stage
:func:`automodal.core.from_time.as_frfdata` picks the route from the data) -> every clear
mode (:func:`~automodal.core.simulate_time.clear_modes`) has a physical mode within 1 %;
the nearest one has its frequency within 0.1 % (hits, random) or 0.5 % (ambient) and its
damping within 10 % (hits, random) or 20 % (ambient) of the exact values. The rules of the
simulation (sample rate, duration) and these tolerances were set while looking at seed 1
only (``benchmarks/bench_time_routes.py --seeds 1``); the tests check seeds 31 and 32
(default) and 41-45 (``slow``), which nothing was tuned on. Every route passes on every
system and seed of these tests (on the benchmark's seeds 51-53 the ambient route misses one
mode of 72: chain3 seed 53, ``benchmarks/results_time_routes.md``); the ambient
(operational) route since its two-pass plan
(:mod:`automodal.core.ambient_plan`, calibrated on seeds 1 and 2) and the reference rule that
sees every peak (before them it failed the 3x2 grid in every seed and had spurious
companions on three other cases).
"""

from __future__ import annotations

import math

import h5py
import numpy as np
import pytest
import scipy.signal
from click.testing import CliRunner

from automodal import Settings, identify
from automodal.cli import main
from automodal.core import simulate as sim
from automodal.core import simulate_time as st
from automodal.core.from_time import as_frfdata
from automodal.io.modes_file import read_modes_json, read_modes_settings
from automodal.io.time_file import read_time

CHECK_SEEDS = (31, 32)
SLOW_SEEDS = (41, 42, 43, 44, 45)


def chain(n: int) -> sim.MechanicalSystem:
    return sim.damp(sim.chain(n), zeta=0.01)


def grid32() -> sim.MechanicalSystem:
    return sim.damp(sim.grid(3, 2), zeta=0.01)


def chain5_np() -> sim.MechanicalSystem:
    return sim.damp(sim.chain(5), "nonproportional", 0.02)


SYSTEMS = {"chain3": chain, "chain4": chain, "chain6": chain, "grid3x2": grid32,
           "chain5np": chain5_np}


def system(name: str) -> sim.MechanicalSystem:
    make = SYSTEMS[name]
    return make(int(name[-1])) if make is chain else make()


# --------------------------------------------------------------------------- simulation


def test_respond_is_the_state_recursion(monkeypatch):
    monkeypatch.setattr(st, "_CHUNK", 1000)  # three blocks
    model = st.discretise(chain(4), None, [1, 3], "acceleration", 100.0, "foh")
    u = np.random.default_rng(0).standard_normal((2500, 2))
    _, y, _ = scipy.signal.dlsim((model.Ad, model.Bd, model.Cd, model.Dd, 0.01), u)
    np.testing.assert_allclose(st.respond(model, u), y, atol=1e-12 * np.abs(y).max())


@pytest.mark.parametrize("hold", st.HOLDS)
def test_discrete_poles_are_the_exact_poles(hold):
    system = chain5_np()
    exact = sim.exact_modes(system)
    model = st.discretise(system, None, [4], "velocity", 80.0, hold)
    z = np.sort_complex(model.z[model.z.imag > 0])
    np.testing.assert_allclose(np.sort_complex(np.exp(exact.poles / 80.0)), z, rtol=1e-12)


@pytest.mark.parametrize("hold", st.HOLDS)
def test_held_sine_gives_the_continuous_steady_state(hold):
    """The samples of a sine, held, are a continuous force whose component at the sine's
    frequency is the sine times the hold's spectrum: ``sinc^2(f / fs)`` (first order: a
    triangle per sample, no delay) or ``sinc(f / fs) exp(-j pi f / fs)`` (zero order: a
    box per sample, half a sample late). The images at ``k fs +- f`` fall far above the
    modes. The simulated steady state is exactly that."""
    system, fs, f = chain(3), 400.0, 10.0
    model = st.discretise(system, None, [2], "displacement", fs, hold)
    t = np.arange(int(60 * fs)) / fs
    y = st.respond(model, np.sin(2 * np.pi * f * t)[:, None])
    H = sim.frf(system, [f], None, [2])[0, :, 0]
    x = f / fs
    hold_gain = np.sinc(x) ** 2 if hold == "foh" else np.sinc(x) * np.exp(-1j * np.pi * x)
    steady = (hold_gain * H[None, :] * np.exp(2j * np.pi * f * t)[:, None]).imag
    tail = t > 50  # transients decayed (tau < 5 s)
    err = np.abs(y[tail] - steady[tail]).max() / np.abs(steady).max()
    assert err < 2e-5, err


def test_default_rules():
    system = chain(4)
    modes = sim.exact_modes(system, None, [3])
    f_max = sim.natural_frequencies_hz(system).max()
    fs = st.default_sample_rate(system)
    assert 3.2 * f_max <= fs < 3.2 * f_max * 1.1
    sigma = st.slowest_decay(modes)
    assert sigma == pytest.approx(np.min(modes.damping_ratio * 2 * np.pi * modes.frequency_hz),
                                  rel=1e-9)
    hits = st.plan("hits", modes, fs, n_hits=4)
    assert hits.hit_spacing / fs == pytest.approx(math.log(1e3) / sigma, rel=1e-3)
    assert hits.n_samples == hits.first_hit + 4 * hits.hit_spacing
    assert st.half_sine_spectrum(hits.pulse_width * fs / 2.56) == pytest.approx(0.5, rel=1e-6)
    random = st.plan("random", modes, fs)
    nperseg = random.rule["nperseg"]
    assert fs / nperseg <= sigma / np.pi / st.LINES_PER_BANDWIDTH  # lines per bandwidth
    assert random.n_samples == 17 * nperseg // 2  # 16 segments at 50 % overlap
    assert st.plan("ambient", modes, fs).duration == pytest.approx(2000 / sigma, rel=1e-3)
    with pytest.raises(ValueError, match="undamped"):
        st.plan("random", sim.exact_modes(sim.damp(sim.chain(3), zeta=0.0)), fs)
    with pytest.raises(ValueError, match="too few"):
        st.plan("hits", modes, fs, duration=1.0, n_hits=5)


def test_simulate_time_test_is_deterministic_and_noisy_as_asked():
    system = chain(3)
    a, modes, plan = st.simulate_time_test(system, None, [2], "random", noise=0.0, seed=5)
    b, _, _ = st.simulate_time_test(system, None, [2], "random", noise=0.0, seed=5)
    np.testing.assert_array_equal(a.outputs, b.outputs)
    np.testing.assert_array_equal(a.inputs, b.inputs)
    assert a.attributes["seed"] == 5 and a.attributes["excitation"] == "random"
    assert a.sample_rate == plan.sample_rate and a.n_samples == plan.n_samples
    model = st.discretise(system, None, [2], "displacement", plan.sample_rate)
    np.testing.assert_allclose(a.outputs, st.respond(model, a.inputs), rtol=0, atol=1e-12)
    noisy, _, _ = st.simulate_time_test(system, None, [2], "random", noise=0.1, seed=5)
    rel = (noisy.outputs - a.outputs).std(axis=0) / a.outputs.std(axis=0)
    np.testing.assert_allclose(rel, 0.1, rtol=0.05)
    ambient, _, _ = st.simulate_time_test(system, [0, 2], None, "ambient", seed=5)
    assert ambient.inputs is None and ambient.output_names == ["dof1", "dof3"]
    np.testing.assert_allclose(modes.poles, sim.exact_modes(system, None, [2]).poles)
    with pytest.raises(ValueError, match="one DOF"):
        st.simulate_time_test(system, None, [0, 1], "hits")


def test_swapped_force_and_response_are_said_not_analysed_silently():
    """A hammer's pulses in a response channel and a ringing force channel are channels
    given the wrong way round (seen with --forces 1 for a file's first column): the random
    route's result carries a warning that says what to do (not a refusal: a spike in a
    response of a true random test looks the same). Random excitation gets no warning."""
    from automodal.timedata import TimeSeries

    ts, _, _ = st.simulate_time_test(chain(3), None, [2], "hits", noise=0.01, seed=2)
    swapped = TimeSeries(outputs=ts.inputs, inputs=ts.outputs[:, [2]],
                         sample_rate=ts.sample_rate, attributes=dict(ts.attributes))
    info = as_frfdata(swapped).attributes["time_analysis"]
    assert info["excitation"] == "random"
    assert any("impulsive" in w and "--forces" in w for w in info["warnings"])
    random, _, _ = st.simulate_time_test(chain(3), None, [2], "random", noise=0.01, seed=2)
    info = as_frfdata(random).attributes["time_analysis"]
    assert info["excitation"] == "random" and not info.get("warnings")


def test_hits_are_separate_decays_the_input_stage_finds():
    ts, _, plan = st.simulate_time_test(chain(3), None, [2], "hits", noise=0.0, seed=2)
    data = as_frfdata(ts)
    info = data.attributes["time_analysis"]
    assert info["excitation"] == "impact" and len(info["hits"]) == plan.n_hits
    assert info["nperseg"] == plan.hit_spacing
    assert info["exponential_decay_per_s"] == 0.0  # each record holds its whole decay
    pulse = ts.inputs[plan.first_hit : plan.first_hit + plan.hit_spacing, 0]
    assert 1 <= np.count_nonzero(pulse) <= math.ceil(plan.pulse_width * plan.sample_rate) + 1


# --------------------------------------------------------------------------- truth tests


def check_truth(name: str, excitation: str, seed: int, f_tol: float, z_tol: float,
                n_bootstrap: int = 30) -> None:
    """Identify a simulated test and compare with its exact modes (see the module notes)."""
    system_ = system(name)
    force = None if excitation == "ambient" else [system_.n_dof - 1]
    ts, modes, plan = st.simulate_time_test(system_, None, force, excitation,
                                            "acceleration", 0.01, seed)
    result = identify(ts, Settings(seed=seed, n_bootstrap=n_bootstrap, jobs=1))
    phys = [m for m in result.modes if m.physical]
    clear = st.clear_modes(modes, plan.sample_rate / 2.56, "acceleration")
    k = st.nearest_modes(modes.frequency_hz[clear], [m.frequency_hz for m in phys])
    missing = modes.frequency_hz[clear][k < 0]
    assert missing.size == 0, f"clear modes not found: {missing} Hz"
    f = np.array([phys[i].frequency_hz for i in k])
    z = np.array([phys[i].damping_ratio for i in k])
    df = np.abs(f / modes.frequency_hz[clear] - 1)
    dz = np.abs(z / modes.damping_ratio[clear] - 1)
    assert df.max() < f_tol, (modes.frequency_hz[clear], df)
    assert dz.max() < z_tol, (modes.frequency_hz[clear], modes.damping_ratio[clear], z)


@pytest.mark.parametrize("seed", CHECK_SEEDS)
@pytest.mark.parametrize("name", ["chain3", "grid3x2", "chain5np"])
def test_truth_hits(name, seed):
    check_truth(name, "hits", seed, 1e-3, 0.10)


@pytest.mark.parametrize("seed", CHECK_SEEDS)
@pytest.mark.parametrize("name", ["chain4", "grid3x2", "chain5np"])
def test_truth_random(name, seed):
    check_truth(name, "random", seed, 1e-3, 0.10)


def test_truth_ambient():
    check_truth("chain3", "ambient", CHECK_SEEDS[0], 5e-3, 0.20)


@pytest.mark.slow
@pytest.mark.parametrize("seed", SLOW_SEEDS)
@pytest.mark.parametrize("name", sorted(SYSTEMS))
@pytest.mark.parametrize("excitation", ["hits", "random"])
def test_truth_h1_routes_sweep(excitation, name, seed):
    check_truth(name, excitation, seed, 1e-3, 0.10)


@pytest.mark.slow
@pytest.mark.parametrize("seed", SLOW_SEEDS)
@pytest.mark.parametrize("name", sorted(SYSTEMS))
def test_truth_ambient_sweep(name, seed):
    check_truth(name, "ambient", seed, 5e-3, 0.20)


# --------------------------------------------------------------------------- CLI


@pytest.mark.parametrize("excitation", ["hits", "random", "ambient"])
def test_cli_writes_time_file_and_exact_modes(tmp_path, excitation):
    out = tmp_path / "t.h5"
    args = ["simulate", str(out), "--dof", "3", "--excitation", excitation, "--seed", "4",
            "--quantity", "velocity", "--sample-rate", "60", "--duration", "40"]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    assert result.output.count("\n") == 1 and "seed 4" in result.output
    ts = read_time(out)
    assert ts.sample_rate == 60.0 and ts.n_samples >= 2390
    assert ts.attributes["quantity"] == "velocity" and ts.attributes["excitation"] == excitation
    inputs = [1, 2, 3] if excitation == "ambient" else [3]
    assert (ts.inputs is None) == (excitation == "ambient")
    with h5py.File(out, "r") as h5:
        assert "frf" not in h5 and "time" in h5
    modes = read_modes_json(tmp_path / "t.modes.json")
    settings = read_modes_settings(tmp_path / "t.modes.json")
    assert settings["excitation"] == excitation and settings["inputs"] == inputs
    assert settings["sample_rate_hz"] == 60.0 and settings["seed"] == 4
    exact = sim.exact_modes(chain(3), None, [i - 1 for i in inputs])
    np.testing.assert_allclose(modes.poles, exact.poles, rtol=1e-12)
    np.testing.assert_allclose(modes.residues, exact.residues, rtol=1e-9, atol=1e-15)
    again = tmp_path / "again.h5"
    assert CliRunner().invoke(main, [args[0], str(again), *args[2:]]).exit_code == 0
    np.testing.assert_array_equal(read_time(again).outputs, ts.outputs)


@pytest.mark.parametrize("args", [
    ["--excitation", "hits", "--lines", "100"],
    ["--excitation", "random", "--pure-noise"],
    ["--duration", "10"],
    ["--hits", "3"],
    ["--excitation", "hits", "--inputs", "1,2"],
    ["--excitation", "random", "--zeta", "0"],
    ["--excitation", "hits", "--duration", "0.1"],
    ["--excitation", "random", "--hits", "3"],  # hits-only options were ignored
    ["--excitation", "ambient", "--pulse-width", "0.01"],
])
def test_cli_time_bad_usage_exits_2(tmp_path, args):
    out = tmp_path / "bad.h5"
    result = CliRunner().invoke(main, ["simulate", str(out), *args])
    assert result.exit_code == 2, result.output
    assert result.output.startswith("automodal: error:") and result.output.count("\n") == 1
    assert not out.exists() and not (tmp_path / "bad.modes.json").exists()


def test_a_folder_where_the_exact_modes_go_is_refused_before_anything_is_written(tmp_path):
    """``<stem>.modes.json`` a folder: exit 2 and no FRF file left behind (it was written
    first, and the modes' write then failed with an internal error)."""
    (tmp_path / "s.modes.json").mkdir()
    result = CliRunner().invoke(main, ["simulate", str(tmp_path / "s.h5")])
    assert result.exit_code == 2, result.output
    assert "is a folder" in result.output and not (tmp_path / "s.h5").exists()
