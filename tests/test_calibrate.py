"""``automodal calibrate``: the FE model, the damping equalization, the calibration and its
bootstrap, the model file and its refusals."""

from __future__ import annotations

import json
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest
import scipy.linalg

import automodal.core.simulate as sim
from automodal.app.calibrate import CalibrationSettings, calibrate_data
from automodal.core import calibration as cal
from automodal.core.damping_equalization import fe_damping, fit_test_model, pair_modes
from automodal.core.fe_model import ParametrizedModel, modal_frf, undamped_modes
from automodal.errors import InputError
from automodal.io.frf_file import write_frf
from automodal.io.model_file import read_model, write_model

N_DOF = 6
DELTA = np.array([-0.2, 0.15, -0.1, 0.2, 0.05, -0.15])
"""The true springs' offsets from the nominal model (-20 .. +20 %)."""


def chain_model(lower: float = 0.3, upper: float = 3.0) -> ParametrizedModel:
    """The nominal 6-DOF chain (1 kg, 1e4 N/m), one parameter per spring, all DOFs
    measured, force at the last DOF."""
    nominal = sim.chain(N_DOF, stiffness=1e4)
    parts = np.array([sim.chain(N_DOF, stiffness=np.eye(N_DOF)[i] * 1e4).K
                      for i in range(N_DOF)])
    return ParametrizedModel(nominal.K, nominal.M, parts, np.zeros_like(parts),
                             tuple(f"k{i + 1}" for i in range(N_DOF)),
                             np.full(N_DOF, lower), np.full(N_DOF, upper),
                             np.arange(N_DOF), np.array([N_DOF - 1]))


def chain_test(seed: int, noise: float = 0.01):
    """The measured chain: springs off by :data:`DELTA`, 1 % Rayleigh damping."""
    truth = sim.damp(sim.chain(N_DOF, stiffness=1e4 * (1 + DELTA)), "rayleigh", 0.01)
    data, modes = sim.simulate_test(truth, np.arange(N_DOF), [N_DOF - 1],
                                    sim.frequency_lines(40.0, 1000), noise=noise, seed=seed)
    return data, modes


# --------------------------------------------------------------------------- core


def test_modal_frf_is_the_direct_solution_with_modal_damping():
    model = chain_model()
    theta = 1 + DELTA
    modes = undamped_modes(model, theta)
    zeta = np.linspace(0.005, 0.03, N_DOF)
    omega = 2 * np.pi * np.array([2.0, 11.0, 25.0])
    K, M = model.matrices(theta)
    # the viscous damping matrix whose modes have those ratios
    lam, phi = scipy.linalg.eigh(K, M)  # mass-normalised
    C = M @ phi @ np.diag(2 * zeta * np.sqrt(lam)) @ phi.T @ M
    for power in (0, 2):
        H = modal_frf(modes, zeta, omega, power)
        for k, w in enumerate(omega):
            direct = np.linalg.inv(K - w**2 * M + 1j * w * C)[:, [N_DOF - 1]] * (1j * w) ** power
            np.testing.assert_allclose(H[k], direct, rtol=1e-9, atol=1e-15)


def test_rigid_body_modes_give_the_mass_line():
    free = sim.chain(3, stiffness=1e4, grounded=False)
    model = ParametrizedModel(free.K, free.M, free.K[None], np.zeros((1, 3, 3)), ("k",),
                              np.array([0.5]), np.array([2.0]), np.arange(3), np.array([0]))
    modes = undamped_modes(model, np.ones(1))
    assert modes.omega[0] == 0.0 and np.all(modes.omega[1:] > 0)
    w = np.array([1e-3])
    H = modal_frf(modes, np.full(3, 0.01), w)
    # far below the elastic modes the free chain moves as one rigid mass of 3 kg
    np.testing.assert_allclose(H[0, :, 0].real, -1 / (3.0 * w[0] ** 2), rtol=1e-3)


def _exact_test_model(theta_true: np.ndarray, power: int = 0):
    truth = sim.damp(sim.chain(N_DOF, stiffness=1e4 * theta_true), "rayleigh", 0.01)
    f = sim.frequency_lines(40.0, 600)
    data, modes = sim.simulate_test(truth, np.arange(N_DOF), [N_DOF - 1], f, noise=0.0, seed=0)
    omega = 2 * np.pi * f
    return omega, data.frf, fit_test_model(omega, data.frf, modes.poles, power), modes


def test_pairing_and_equalized_damping_follow_the_test_modes():
    omega, H, test, modes = _exact_test_model(1 + DELTA)
    fe = undamped_modes(chain_model(), np.ones(N_DOF))  # nominal: frequencies 1-5 % off
    pairs = pair_modes(fe, test)
    assert len(pairs) == N_DOF
    for i, j in pairs:  # each test mode with the FE mode of the same rank
        assert np.argsort(np.argsort(test.frequency_hz))[i] == j
    zeta = fe_damping(fe, test, "paired", fallback=0.5)
    np.testing.assert_allclose(np.sort(zeta), np.sort(modes.damping_ratio), rtol=1e-6)
    assert np.all(fe_damping(fe, test, "none", fallback=0.02) == 0.02)
    assert np.all(fe_damping(fe, test, "common", fallback=0.02, common=0.05) == 0.05)


def test_deviation_vanishes_at_the_truth_and_calibration_finds_it():
    omega, H, test, _ = _exact_test_model(1 + DELTA)
    problem = cal.CalibrationProblem(chain_model(), omega, np.ones(H.shape), 0)
    assert cal.deviation(problem, 1 + DELTA, test) < 1e-12
    assert cal.deviation(problem, np.ones(N_DOF), test) > 1e-2
    fit = cal.calibrate(problem, test, np.ones(N_DOF))
    assert fit.converged
    np.testing.assert_allclose(fit.theta, 1 + DELTA, rtol=1e-6)


def test_two_stage_calibration_reaches_the_truth_from_far_away():
    omega, H, test, _ = _exact_test_model(1 + DELTA)
    problem = cal.CalibrationProblem(chain_model(0.2, 5.0), omega, np.ones(H.shape), 0,
                                     common_damping=0.05)
    start = (1 + DELTA) * (1 + 0.7 * np.array([1, -1, 1, 1, -1, 1]))
    fit = cal.calibrate_in_two_stages(problem, test, start)
    np.testing.assert_allclose(fit.theta, 1 + DELTA, rtol=1e-5)


def test_bootstrap_does_not_depend_on_the_worker_count():
    data, modes = chain_test(seed=3)
    omega, H = data.omega, data.frf
    variance = (0.01 * np.abs(H)) ** 2
    test = fit_test_model(omega, H, modes.poles, 0, variance)
    problem = cal.CalibrationProblem(chain_model(), omega, cal.snr_weights(test.frf(omega),
                                                                           variance), 0)
    theta = cal.calibrate(problem, test, np.ones(N_DOF)).theta
    one = cal.bootstrap_calibrations(problem, H, variance, test, theta, 4, seed=5, jobs=1)
    two = cal.bootstrap_calibrations(problem, H, variance, test, theta, 4, seed=5, jobs=2)
    np.testing.assert_array_equal(one.theta, two.theta)
    assert one.converged.all()
    assert np.ptp(one.theta, axis=0).max() > 0  # the datasets differ


# --------------------------------------------------------------------------- the whole run


def _acceptance(seed: int, n_bootstrap: int) -> tuple[dict, float]:
    data, _ = chain_test(seed)
    t0 = time.perf_counter()
    outcome = calibrate_data(data, chain_model(),
                             CalibrationSettings(seed=seed, n_bootstrap=n_bootstrap))
    return outcome.result, time.perf_counter() - t0


def test_chain_calibration_acceptance():
    """The issue's case: six springs off by -20..+20 %, 1 % noise, 6 outputs: every
    parameter within 3 %, at least 5 of the 6 95 % intervals hold the truth, <= 60 s
    (about 13 s on a busy 2-core machine, so not marked slow)."""
    result, runtime = _acceptance(seed=1, n_bootstrap=100)
    value = np.array([p["value"] for p in result["parameters"]])
    ci = np.array([p["ci95"] for p in result["parameters"]])
    truth = 1 + DELTA
    assert np.all(np.abs(value / truth - 1) < 0.03), value
    assert np.sum((ci[:, 0] <= truth) & (truth <= ci[:, 1])) >= 5, (ci, truth)
    assert result["bootstrap"]["converged"] == 100
    assert runtime <= 60.0, runtime
    assert result["deviation"]["after"] < 0.01 * result["deviation"]["before"]
    assert [m["fe_mode"] for m in result["modes"]] == list(range(1, N_DOF + 1))


# --------------------------------------------------------------------------- model file


def test_model_file_round_trip(tmp_path):
    model = chain_model(0.5, 2.0)
    path = tmp_path / "m.h5"
    write_model(path, model)
    back = read_model(path)
    assert back.names == model.names
    np.testing.assert_array_equal(back.stiffness_parts, model.stiffness_parts)
    np.testing.assert_array_equal(back.lower, 0.5)
    np.testing.assert_array_equal(back.outputs, np.arange(N_DOF))


def _spoil(path, edit):
    write_model(path, chain_model())
    with h5py.File(path, "a") as f:
        edit(f)


def _replace(f, name, value):
    del f[name]
    f[name] = value


BAD_MODELS = {
    "not-square": (lambda f: _replace(f, "stiffness", np.ones((6, 5))), "square"),
    "mass-shape": (lambda f: _replace(f, "mass", np.eye(5)), "expected (6, 6)"),
    "asymmetric": (lambda f: _replace(f, "stiffness", np.triu(f["stiffness"][()])),
                   "not symmetric"),
    "indefinite-mass": (lambda f: _replace(f, "mass", -np.eye(6)), "positive definite"),
    "indefinite-part": (lambda f: _replace(f, "parameters/k1/stiffness",
                                           -f["parameters/k1/stiffness"][()]), "indefinite"),
    "indefinite-at-lower": (lambda f: f["parameters/k1"].attrs.__setitem__("lower", 1e-3)
                            or _replace(f, "stiffness", f["stiffness"][()]
                                        - 0.9 * f["parameters/k1/stiffness"][()]),
                            "lower bounds"),
    "dof-out-of-range": (lambda f: _replace(f, "outputs/dof", np.array([0, 1, 2, 3, 4, 6])),
                         "out of range"),
    "negative-dof": (lambda f: _replace(f, "inputs/dof", np.array([-1])), "out of range"),
    "bounds-exclude-1": (lambda f: f["parameters/k2"].attrs.__setitem__("lower", 1.1),
                         "bounds"),
    "upper-below-1": (lambda f: f["parameters/k2"].attrs.__setitem__("upper", 0.9), "bounds"),
    "no-parameters": (lambda f: f.__delitem__("parameters"), "/parameters"),
    "empty-parameter": (lambda f: [f["parameters/k3"].__delitem__("stiffness")],
                        "neither a stiffness nor a mass"),
    "nan": (lambda f: _replace(f, "mass", np.full((6, 6), np.nan)), "not finite"),
    "complex": (lambda f: _replace(f, "mass", np.eye(6) + 0j), "real numbers"),
    "bad-damping": (lambda f: f.__setitem__("damping", 1.5), "/damping"),
    "missing-inputs": (lambda f: f.__delitem__("inputs"), "/inputs/dof"),
}


@pytest.mark.parametrize("case", sorted(BAD_MODELS))
def test_bad_model_file_is_refused_in_one_line(tmp_path, case):
    edit, words = BAD_MODELS[case]
    path = tmp_path / "bad.h5"
    _spoil(path, edit)
    with pytest.raises(InputError) as err:
        read_model(path)
    message = str(err.value)
    assert "\n" not in message and str(path) in message
    assert words in message, message


def _run_cli(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "automodal", "calibrate", *map(str, args)],
                          capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("case", ["asymmetric", "dof-out-of-range", "bounds-exclude-1",
                                  "channels"])
def test_cli_refuses_a_bad_model_file(tmp_path, case):
    frf = tmp_path / "test.h5"
    write_frf(frf, chain_test(seed=1)[0])
    bad = tmp_path / "model.h5"
    if case == "channels":  # a valid model whose outputs do not match the FRF file's
        _spoil(bad, lambda f: _replace(f, "outputs/dof", np.array([0, 1, 2])))
    else:
        _spoil(bad, BAD_MODELS[case][0])
    out = tmp_path / "r.json"
    proc = _run_cli(frf, bad, "-o", out)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("automodal: error: "), proc.stderr
    assert "model.h5" in lines[0]
    assert not out.exists()
    assert not any(p.name.startswith(".r.json") for p in tmp_path.iterdir())


def test_cli_writes_the_result_and_figures(tmp_path):
    frf = tmp_path / "test.h5"
    write_frf(frf, chain_test(seed=2)[0])
    model = tmp_path / "model.h5"
    write_model(model, chain_model())
    out = tmp_path / "r.json"
    proc = _run_cli(frf, model, "-o", out, "--bootstrap", "3", "--seed", "4", "--plot",
                    tmp_path / "fig")
    assert proc.returncode == 0, proc.stderr
    result = json.loads(out.read_text())
    assert result["format"] == "automodal-calibration"
    assert {"name", "value", "std", "ci95"} <= set(result["parameters"][0])
    assert result["settings"]["seed"] == 4
    assert (tmp_path / "fig" / "frf_overlay.png").stat().st_size > 0
    assert (tmp_path / "fig" / "parameters.png").stat().st_size > 0
    assert "k6" in proc.stdout


def test_calibration_figures_draw_the_curves_and_label_the_axes():
    """The overlay draws the four curves of every entry (measured under the test data model,
    FE calibrated dashed) with units on the magnitude axis; the histograms are in percent of
    the calibrated value, each titled with its value and interval (issue 15: readable ticks
    where the bootstrap spread is 1e-5 of the value)."""
    from automodal.app.calibration_plots import frf_overlay, parameter_distributions

    data, _ = chain_test(seed=2)
    outcome = calibrate_data(data, chain_model(), CalibrationSettings(n_bootstrap=8, seed=1))
    fig = frf_overlay(outcome)
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == N_DOF
    assert axes[0].get_ylabel() == "|H| receptance (m/N)"
    labels = [line.get_label() for line in axes[0].get_lines()]
    assert labels == ["measured", "test data model", "FE nominal", "FE calibrated"]
    measured, _, _, calibrated = axes[2].get_lines()
    np.testing.assert_allclose(measured.get_ydata(), np.abs(outcome.measured[:, 2, 0]))
    assert calibrated.get_linestyle() == "--" and measured.get_linewidth() > 2
    assert "entries" not in fig.get_suptitle()  # all six drawn

    fig = parameter_distributions(outcome)
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == N_DOF
    first = outcome.result["parameters"][0]
    assert axes[0].get_title().startswith(f"{first['name']} = {first['value']:.5g}")
    assert axes[0].get_xlabel() == "change from the calibrated value (%)"
    assert axes[0].get_ylabel() == "bootstrap datasets"
    counts = sum(patch.get_height() for patch in axes[0].patches)
    assert counts == outcome.replicate_theta.shape[0]
    fig.canvas.draw()  # tick labels need a draw: no offset text, plain percentages
    assert axes[0].xaxis.get_offset_text().get_text() == ""
