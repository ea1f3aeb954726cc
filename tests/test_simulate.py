"""Tests of the synthetic-test generator: automodal.core.simulate, the modes file, the CLI."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
import scipy.linalg
from click.testing import CliRunner

from automodal.cli import main
from automodal.core import simulate as sim
from automodal.core.modal import mpc
from automodal.errors import InputError
from automodal.io.frf_file import read_frf
from automodal.io.modes_file import read_modes_json, read_modes_settings, write_modes_json


@pytest.fixture(scope="module")
def chain_t1() -> sim.MechanicalSystem:
    """The 8-DOF chain of validation target T1: Rayleigh 0.5 M + 1e-5 K."""
    s = sim.chain(8)
    return sim.MechanicalSystem(s.M, s.K, sim.rayleigh(s.M, s.K, 0.5, 1e-5), s.xyz, s.meta)


@pytest.fixture(scope="module")
def grid_np() -> sim.MechanicalSystem:
    """A 3x4 grid with non-proportional damping (complex modes)."""
    return sim.damp(sim.grid(3, 4), "nonproportional", 0.01)


def _band(system: sim.MechanicalSystem, n: int = 400) -> np.ndarray:
    return sim.frequency_lines(1.25 * sim.natural_frequencies_hz(system).max(), n)


def _transfer(ss: sim.StateSpace, frequency_hz: np.ndarray) -> np.ndarray:
    """C (j w I - A)^-1 B + D, straight from the definition."""
    A, B, C, D = ss
    s = 2j * np.pi * frequency_hz
    X = np.linalg.solve(s[:, None, None] * np.eye(A.shape[0]) - A,
                        np.broadcast_to(B, (s.size, *B.shape)))
    return C @ X + D


# --------------------------------------------------------------------------- systems


def test_chain_matrices():
    s = sim.chain(3, mass=[1.0, 2.0, 3.0], stiffness=[10.0, 20.0, 30.0])
    np.testing.assert_array_equal(s.M, np.diag([1.0, 2.0, 3.0]))
    np.testing.assert_array_equal(s.K, [[30, -20, 0], [-20, 50, -30], [0, -30, 30]])
    np.testing.assert_array_equal(s.C, np.zeros((3, 3)))
    free = sim.chain(3, stiffness=[20.0, 30.0], grounded=False)
    np.testing.assert_array_equal(free.K, [[20, -20, 0], [-20, 50, -30], [0, -30, 30]])
    with pytest.raises(ValueError, match="stiffness needs 3"):
        sim.chain(3, stiffness=[1.0, 2.0])


def test_t1_frequencies(chain_t1):
    """The chain reproduces the published T1 frequencies of method-notes.md."""
    true = [2.937, 8.711, 14.188, 19.183, 23.523, 27.063, 29.682, 31.289]
    modes = sim.exact_modes(chain_t1, [1, 4, 7])
    np.testing.assert_allclose(modes.frequency_hz, true, atol=1.5e-3)
    assert modes.shapes.shape == (3, 8)


def test_grid_modes_distinct_by_default_and_repeated_when_symmetric():
    f = sim.natural_frequencies_hz(sim.grid(3, 4))
    assert np.min(np.diff(f) / f[1:]) > 0.03
    f_sym = sim.natural_frequencies_hz(sim.grid(3, 3, symmetric=True))
    assert np.min(np.diff(f_sym) / f_sym[1:]) < 1e-10
    g = sim.grid(2, 3)
    np.testing.assert_allclose(g.K, g.K.T)
    # DOF ix + nx * iy sits at (ix, iy)
    np.testing.assert_array_equal(g.xyz[3], [1.0, 1.0, 0.0])


def test_free_chain_drops_rigid_body_mode():
    s = sim.damp(sim.chain(4, grounded=False), "rayleigh", 0.01)
    modes = sim.exact_modes(s)
    assert modes.n_modes == 3
    assert np.all(modes.frequency_hz > 1.0)


def test_combine_is_block_diagonal():
    a, b = sim.chain(2), sim.chain(3)
    c = sim.combine(a, b)
    assert c.n_dof == 5
    np.testing.assert_array_equal(c.K[:2, :2], a.K)
    np.testing.assert_array_equal(c.K[2:, 2:], b.K)
    assert not c.K[:2, 2:].any()


# --------------------------------------------------------------------------- damping


def test_rayleigh_coefficients_hit_the_anchor_ratios():
    alpha, beta = sim.rayleigh_coefficients(2.0, 30.0, 0.01, 0.02)
    for f, z in [(2.0, 0.01), (30.0, 0.02)]:
        w = 2 * np.pi * f
        assert alpha / (2 * w) + beta * w / 2 == pytest.approx(z)


def test_damp_rayleigh_gives_zeta_at_end_modes():
    modes = sim.exact_modes(sim.damp(sim.chain(6), "rayleigh", 0.01))
    assert modes.damping_ratio[0] == pytest.approx(0.01, rel=1e-9)
    assert modes.damping_ratio[-1] == pytest.approx(0.01, rel=1e-9)
    assert np.all(modes.damping_ratio <= 0.01 + 1e-12)
    np.testing.assert_allclose(mpc(modes.shapes), 1.0, atol=1e-10)


def test_damp_nonproportional_gives_complex_modes(grid_np):
    modes = sim.exact_modes(grid_np)
    assert np.all((modes.damping_ratio > 0.003) & (modes.damping_ratio < 0.03))
    assert mpc(modes.shapes).min() < 0.99
    # not a linear combination of M and K
    coef, *_ = np.linalg.lstsq(np.column_stack([grid_np.M.ravel(), grid_np.K.ravel()]),
                               grid_np.C.ravel(), rcond=None)
    assert np.abs(coef[0] * grid_np.M + coef[1] * grid_np.K - grid_np.C).max() > 0.1


def test_dashpots_matrix():
    C = sim.dashpots(3, [(0, 2), (1, None)], [2.0, 5.0])
    np.testing.assert_array_equal(C, [[2, 0, -2], [0, 5, 0], [-2, 0, 2]])
    with pytest.raises(ValueError, match="out of range"):
        sim.dashpots(3, [(0, 3)], 1.0)


# --------------------------------------------------------------------------- modes


def test_exact_modes_match_undamped_eig(chain_t1):
    """Light proportional damping: |lambda| and the shapes are those of K phi = w^2 M phi."""
    lam, phi = scipy.linalg.eig(chain_t1.K, chain_t1.M)
    order = np.argsort(lam.real)
    omega = np.sqrt(lam.real[order])
    phi = phi[:, order].real
    outputs = [0, 3, 7]
    modes = sim.exact_modes(chain_t1, outputs)
    np.testing.assert_allclose(2 * np.pi * modes.frequency_hz, omega, rtol=1e-10)
    np.testing.assert_allclose(modes.damping_ratio, 0.5 / (2 * omega) + 1e-5 * omega / 2,
                               rtol=1e-8)
    ref = phi[outputs] / phi[outputs][np.argmax(np.abs(phi[outputs]), axis=0), range(8)]
    np.testing.assert_allclose(modes.shapes, ref, atol=1e-10)
    assert np.all(np.abs(modes.shapes).max(axis=0) == pytest.approx(1.0))
    assert np.all(modes.poles.imag > 0)
    assert np.all(np.diff(modes.frequency_hz) > 0)


def test_shapes_normalised_to_unit_max(grid_np):
    modes = sim.exact_modes(grid_np, [0, 4, 11])
    idx = np.argmax(np.abs(modes.shapes), axis=0)
    np.testing.assert_allclose(modes.shapes[idx, range(modes.n_modes)], 1.0, atol=1e-12)


# --------------------------------------------------------------------------- FRF


@pytest.mark.parametrize("quantity", sim.QUANTITIES)
def test_frf_equals_state_space(grid_np, quantity):
    f = _band(grid_np)
    outputs, inputs = [0, 5, 11, 7], [11, 2]
    H = sim.frf(grid_np, f, outputs, inputs, quantity)
    ss = sim.state_space(grid_np, outputs, inputs, quantity)
    assert H.shape == (f.size, 4, 2)
    assert ss.D.any() == (quantity == "acceleration")
    np.testing.assert_allclose(_transfer(ss, f), H, rtol=0, atol=1e-10 * np.abs(H).max())


@pytest.mark.parametrize("quantity", sim.QUANTITIES)
def test_frf_equals_modal_sum(grid_np, quantity):
    f = _band(grid_np)
    modes = sim.exact_modes(grid_np, [1, 6, 9], [0, 11])
    H = sim.frf(grid_np, f, [1, 6, 9], [0, 11], quantity)
    np.testing.assert_allclose(sim.modal_frf(modes, f, quantity), H, rtol=0,
                               atol=1e-10 * np.abs(H).max())


def test_frf_is_the_inverse_dynamic_stiffness(grid_np):
    f = np.array([3.0, 17.5])
    H = sim.frf(grid_np, f)
    for k, fk in enumerate(f):
        w = 2 * np.pi * fk
        Z = grid_np.K - w**2 * grid_np.M + 1j * w * grid_np.C
        np.testing.assert_allclose(H[k], np.linalg.inv(Z), rtol=1e-10, atol=1e-16)


def test_quantities_relate_by_jw(chain_t1):
    f = _band(chain_t1)
    jw = (2j * np.pi * f)[:, None, None]
    d, v, a = (sim.frf(chain_t1, f, [0, 7], [7], q) for q in sim.QUANTITIES)
    np.testing.assert_allclose(v, jw * d, rtol=1e-12)
    np.testing.assert_allclose(a, jw * v, rtol=1e-12)


def test_frf_of_a_large_grid_in_chunks():
    s = sim.damp(sim.grid(8, 10), "nonproportional")
    f = np.linspace(1.0, 40.0, 3000)
    H = sim.frf(s, f, None, [0, 79])
    assert H.shape == (3000, 80, 2)
    # the chunked solve equals a direct solve at a few lines
    for k in (0, 1234, 2999):
        w = 2 * np.pi * f[k]
        Z = s.K - w**2 * s.M + 1j * w * s.C
        assert np.allclose(H[k], np.linalg.inv(Z)[:, [0, 79]], rtol=1e-10, atol=0)


def test_frequency_lines_avoid_zero():
    f = sim.frequency_lines(10.0, 100)
    assert f[0] == pytest.approx(0.1) and f[-1] == 10.0 and f.size == 100
    np.testing.assert_allclose(np.diff(f), 0.1)
    np.testing.assert_allclose(sim.frequency_lines(10.0, 11, 0.0), np.arange(11.0))


# --------------------------------------------------------------------------- noise


def test_proportional_noise_statistics():
    H = np.exp(1j * np.linspace(0, 20, 200_000)) * np.linspace(1e-3, 10, 200_000)
    level = 0.05
    rel = (sim.add_noise(H, level, np.random.default_rng(1)) - H) / np.abs(H)
    assert rel.real.std() == pytest.approx(level / np.sqrt(2), rel=0.01)
    assert rel.imag.std() == pytest.approx(level / np.sqrt(2), rel=0.01)
    assert abs(rel.mean()) < 0.001
    assert abs(np.mean(rel.real * rel.imag)) < 1e-5


def test_additive_noise_statistics():
    rng = np.random.default_rng(2)
    H = np.zeros((100_000, 2, 1), complex)
    H[:, 0, 0] = 3.0 * np.exp(1j * rng.uniform(0, 6, 100_000))
    H[:100, 1, 0] = 1.0  # RMS over lines 0.1*0.316
    noisy = sim.add_noise(H, 0.02, rng, kind="additive")
    e = noisy - H
    assert np.std(e[:, 0, 0]) == pytest.approx(0.02 * 3.0, rel=0.01)
    assert np.std(e[:, 1, 0]) == pytest.approx(0.02 * np.sqrt(100 / 100_000), rel=0.01)
    # the same std at every line, however small |H| is there
    assert np.std(e[100:, 1, 0]) == pytest.approx(np.std(e[:100, 1, 0]), rel=0.3)


def test_noise_arguments():
    H = np.ones((5, 1, 1), complex)
    np.testing.assert_array_equal(sim.add_noise(H, 0.0, 0), H)
    with pytest.raises(ValueError, match="noise kind"):
        sim.add_noise(H, 0.1, 0, kind="pink")
    with pytest.raises(ValueError, match=">= 0"):
        sim.add_noise(H, -0.1, 0)


# --------------------------------------------------------------------------- simulate_test


def test_simulate_test_is_deterministic_under_seed(grid_np):
    f = _band(grid_np, 200)
    a, ma = sim.simulate_test(grid_np, [0, 5], [11], f, "velocity", 0.02, seed=42)
    b, mb = sim.simulate_test(grid_np, [0, 5], [11], f, "velocity", 0.02, seed=42)
    c, _ = sim.simulate_test(grid_np, [0, 5], [11], f, "velocity", 0.02, seed=43)
    np.testing.assert_array_equal(a.frf, b.frf)
    np.testing.assert_array_equal(ma.shapes, mb.shapes)
    assert not np.array_equal(a.frf, c.frf)
    assert a.attributes["seed"] == 42
    d, _ = sim.simulate_test(grid_np, [0, 5], [11], f, "velocity", 0.02, seed=None)
    e, _ = sim.simulate_test(grid_np, [0, 5], [11], f, "velocity", 0.02,
                             seed=d.attributes["seed"])
    np.testing.assert_array_equal(d.frf, e.frf)


def test_simulate_test_fills_frfdata(grid_np):
    f = _band(grid_np, 200)
    data, modes = sim.simulate_test(grid_np, [0, 5, 11], [11, 0], f, "acceleration", 0.0, 1)
    np.testing.assert_array_equal(data.frf, sim.frf(grid_np, f, [0, 5, 11], [11, 0],
                                                    "acceleration"))
    assert data.quantity == "acceleration"
    assert data.output_names == ["dof1", "dof6", "dof12"]
    assert data.input_names == ["dof12", "dof1"]
    np.testing.assert_array_equal(data.output_nodes, [1, 6, 12])
    np.testing.assert_array_equal(data.output_xyz, grid_np.xyz[[0, 5, 11]])
    assert modes.n_outputs == 3 and modes.residues.shape == (12, 3, 2)


def test_pure_noise_has_no_structure(chain_t1):
    f = _band(chain_t1, 2000)
    clean = sim.frf(chain_t1, f, [7], [7])
    data, modes = sim.simulate_test(chain_t1, [7], [7], f, pure_noise=True, seed=3)
    assert modes.n_modes == 0 and modes.shapes.shape == (1, 0)
    h = data.frf[:, 0, 0]
    assert np.sqrt(np.mean(np.abs(h) ** 2)) == pytest.approx(
        np.sqrt(np.mean(np.abs(clean) ** 2)), rel=0.1)
    # white: neighbouring lines uncorrelated (the clean FRF is strongly correlated)
    assert abs(np.vdot(h[:-1], h[1:])) / np.vdot(h, h).real < 0.1
    assert abs(np.vdot(clean[:-1, 0, 0], clean[1:, 0, 0])) / np.vdot(clean, clean).real > 0.9


# --------------------------------------------------------------------------- modes file


def test_modes_json_round_trip(tmp_path, grid_np):
    modes = sim.exact_modes(grid_np, [0, 3], [11])
    path = tmp_path / "x.modes.json"
    write_modes_json(path, modes, {"seed": np.int64(5), "band_hz": np.array([0.1, 40.0])})
    back = read_modes_json(path)
    for name in ("poles", "frequency_hz", "damping_ratio", "shapes", "residues"):
        np.testing.assert_array_equal(getattr(back, name), getattr(modes, name))
    assert read_modes_settings(path) == {"seed": 5, "band_hz": [0.1, 40.0]}
    assert [p.name for p in tmp_path.iterdir()] == ["x.modes.json"]


def test_modes_json_refuses_bad_files(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_modes_json(tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(InputError, match="bad.json: not a readable JSON"):
        read_modes_json(bad)
    bad.write_text(json.dumps({"format": "something-else"}))
    with pytest.raises(InputError, match="not an automodal modes file"):
        read_modes_json(bad)
    write_modes_json(bad, sim.Modes.empty(2))
    doc = json.loads(bad.read_text())
    doc["n_modes"] = 1
    bad.write_text(json.dumps(doc))
    with pytest.raises(InputError, match="inconsistent"):
        read_modes_json(bad)


# --------------------------------------------------------------------------- CLI


def test_cli_writes_both_files(tmp_path):
    out = tmp_path / "chain6.h5"
    args = ["simulate", str(out), "--dof", "6", "--inputs", "6", "--lines", "500", "--seed", "1"]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    assert result.output.count("\n") == 1 and "seed 1" in result.output
    with h5py.File(out, "r") as h5:
        assert h5.attrs["format"] == "automodal-frf"
        assert h5.attrs["quantity"] == "displacement"
        H = h5["frf"][()]
        f = h5["frequency"][()]
    assert H.shape == (500, 6, 1) and f[0] > 0
    data = read_frf(out)
    assert data.input_names == ["dof6"] and data.attributes["seed"] == 1
    np.testing.assert_array_equal(data.frf, H)
    modes = read_modes_json(tmp_path / "chain6.modes.json")
    settings = read_modes_settings(tmp_path / "chain6.modes.json")
    assert settings["seed"] == 1 and settings["inputs"] == [6]
    assert settings["outputs"] == [1, 2, 3, 4, 5, 6]
    system = sim.damp(sim.chain(6), "rayleigh", 0.01)
    exact = sim.exact_modes(system, range(6), [5])
    np.testing.assert_allclose(modes.frequency_hz, exact.frequency_hz, rtol=1e-12)
    np.testing.assert_allclose(modes.shapes, exact.shapes, atol=1e-12)
    assert np.all((modes.frequency_hz > 20 * f[0]) & (modes.frequency_hz < f[-1]))
    # the same seed gives the same file content
    CliRunner().invoke(main, args[:1] + [str(tmp_path / "again.h5")] + args[2:])
    with h5py.File(tmp_path / "again.h5", "r") as h5:
        np.testing.assert_array_equal(h5["frf"][()], H)


def test_cli_grid_options_and_quiet(tmp_path):
    out = tmp_path / "g.h5"
    result = CliRunner().invoke(main, [
        "simulate", str(out), "--system", "grid", "--grid", "3", "4", "--outputs", "1,3,5-8",
        "--inputs", "1,12", "--quantity", "acceleration", "--damping", "nonproportional",
        "--fmin", "1", "--fmax", "50", "--lines", "300", "--seed", "2", "--quiet"])
    assert result.exit_code == 0, result.output
    assert result.output == ""
    with h5py.File(out, "r") as h5:
        assert h5["frf"].shape == (300, 6, 2)
        np.testing.assert_allclose(h5["frequency"][[0, -1]], [1.0, 50.0])
        assert h5.attrs["quantity"] == "acceleration"
    modes = read_modes_json(tmp_path / "g.modes.json")
    assert modes.n_modes == 12 and mpc(modes.shapes).min() < 0.999


def test_cli_pure_noise(tmp_path):
    result = CliRunner().invoke(main, ["simulate", str(tmp_path / "n.h5"), "--pure-noise",
                                       "--seed", "7", "-q"])
    assert result.exit_code == 0, result.output
    assert read_modes_json(tmp_path / "n.modes.json").n_modes == 0


@pytest.mark.parametrize("args", [
    ["--outputs", "0,2"], ["--inputs", "7"], ["--outputs", "1,1"], ["--outputs", "x"],
    ["--fmin", "100", "--fmax", "50"],
])
def test_cli_bad_usage_exits_2(tmp_path, args):
    out = tmp_path / "bad.h5"
    result = CliRunner().invoke(main, ["simulate", str(out), *args])
    assert result.exit_code == 2
    assert not out.exists() and not (tmp_path / "bad.modes.json").exists()


def test_cli_folder_that_cannot_be_made_exits_2(tmp_path):
    (tmp_path / "file").write_text("")
    result = CliRunner().invoke(main, ["simulate", str(tmp_path / "file" / "no" / "x.h5")])
    assert result.exit_code == 2
    assert "is not a folder" in result.output


def test_cli_help_has_example():
    result = CliRunner().invoke(main, ["simulate", "--help"])
    assert result.exit_code == 0
    assert "automodal simulate chain6.h5" in result.output
