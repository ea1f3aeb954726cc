"""Settings are validated on creation: one test per field, and the CLI's exit status."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from automodal.errors import InputError
from automodal.settings import Settings, SettingsError

ROOT = Path(__file__).resolve().parents[1]


def _refused(field: str, **kw) -> SettingsError:
    with pytest.raises(SettingsError, match=rf"setting {field} = .* must be") as info:
        Settings(**kw)
    return info.value


def test_defaults_are_valid_and_to_dict_is_unchanged():
    s = Settings()
    assert s.to_dict() == {
        "band_hz": None, "n_bootstrap": 100, "seed": 0, "max_order": None, "threshold": 0.8,
        "zeta_max": 0.2, "min_physicalness": 0.5, "coalescence": 1.0, "resample": "auto",
            "weighting": "auto", "sub_bands": True, "block_rows": None,
    }
    assert Settings(band_hz=(1, 20)).to_dict()["band_hz"] == [1.0, 20.0]


def test_error_is_an_input_error_and_a_value_error():
    err = _refused("seed", seed=-1)
    assert isinstance(err, InputError) and isinstance(err, ValueError)
    assert "\n" not in str(err)


def test_settings_are_frozen_and_replace_validates():
    s = Settings()
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.seed = 3  # type: ignore[misc]
    with pytest.raises(SettingsError, match="jobs"):
        dataclasses.replace(s, jobs=0)


@pytest.mark.parametrize("band", [(10.0, 5.0), (5.0, 5.0), (-1.0, 5.0), (0.0, np.inf),
                                  (np.nan, 4.0), (1.0,), "ab", (1.0, "2")])
def test_band_hz(band):
    err = _refused("band_hz", band_hz=band)
    assert "0 <= lo < hi" in str(err)
    assert Settings(band_hz=[0, 5]).band_hz == (0.0, 5.0)
    assert Settings(band_hz=(np.float32(1), np.int64(3))).band_hz == (1.0, 3.0)


@pytest.mark.parametrize("value", [0, -3, 2.5, "10", True])
def test_n_bootstrap(value):
    assert "integer >= 1" in str(_refused("n_bootstrap", n_bootstrap=value))
    assert Settings(n_bootstrap=1).n_bootstrap == 1
    assert Settings(n_bootstrap=np.int64(7)).n_bootstrap == 7


@pytest.mark.parametrize("value", [-1, 1.0, None, "0"])
def test_seed(value):
    assert "integer >= 0" in str(_refused("seed", seed=value))
    assert Settings(seed=0).seed == 0


@pytest.mark.parametrize("value", [3, 2, 0, -4, 10.0, "20"])
def test_max_order(value):
    assert "integer >= 4" in str(_refused("max_order", max_order=value))
    assert Settings(max_order=5).max_order == 5  # rounded down to 4 by the order selection
    assert Settings(max_order=None).max_order is None


@pytest.mark.parametrize("value", [1, 0, -2, 4.0, "8", True])
def test_block_rows(value):
    assert "integer >= 2" in str(_refused("block_rows", block_rows=value))
    assert Settings(block_rows=2).block_rows == 2
    assert type(Settings(block_rows=np.int64(14)).to_dict()["block_rows"]) is int
    assert Settings(block_rows=None).block_rows is None


@pytest.mark.parametrize("value", [0, -1, 1.5, "2"])
def test_jobs(value):
    assert "None (all cores) or an integer >= 1" in str(_refused("jobs", jobs=value))
    assert Settings(jobs=1).jobs == 1 and Settings().jobs is None


@pytest.mark.parametrize("value", [0.0, -0.1, 1.01, np.nan, "0.8"])
def test_threshold(value):
    assert "(0, 1]" in str(_refused("threshold", threshold=value))
    assert Settings(threshold=1.0).threshold == 1.0


@pytest.mark.parametrize("value", [0.0, 1.0, 1.5, -0.2, np.inf])
def test_zeta_max(value):
    assert "(0, 1)" in str(_refused("zeta_max", zeta_max=value))
    assert Settings(zeta_max=0.99).zeta_max == 0.99


@pytest.mark.parametrize("value", [0.0, -0.01, 1.01, np.nan, None])
def test_min_physicalness(value):
    assert "(0, 1]" in str(_refused("min_physicalness", min_physicalness=value))
    assert Settings(min_physicalness=0.01).min_physicalness == 0.01
    assert Settings(min_physicalness=1).min_physicalness == 1


@pytest.mark.parametrize("value", [0.0, -1.0, np.inf, np.nan])
def test_coalescence(value):
    assert "> 0" in str(_refused("coalescence", coalescence=value))
    assert Settings(coalescence=0.1).coalescence == 0.1


@pytest.mark.parametrize("value", ["line", "", None, "AUTO"])
def test_resample(value):
    assert "'auto', 'lines', 'records'" in str(_refused("resample", resample=value))
    for ok in ("auto", "lines", "records"):
        assert Settings(resample=ok).resample == ok


def _cli(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    return subprocess.run([sys.executable, "-m", "automodal", *args], capture_output=True,
                          text=True, cwd=ROOT, env=env, timeout=120)


@pytest.mark.parametrize("args", [("--jobs", "0"), ("--seed", "-1"), ("--bootstrap", "0")])
def test_cli_refuses_a_bad_setting_with_exit_2_and_one_line(args):
    p = _cli("identify", "sample_data/chain6.h5", "--quiet", *args)
    assert p.returncode == 2, p.stderr
    assert len(p.stderr.strip().splitlines()) == 1, p.stderr
    assert p.stderr.startswith("automodal: error: ")
    assert args[0].lstrip("-") in p.stderr


def test_auto_weighting_is_noise_for_frfs_and_envelope_for_output_only():
    s = Settings()
    assert s.weighting == "auto"
    assert s.weighting_for(operational=False) == "noise"
    assert s.weighting_for(operational=True) == "envelope"
    assert Settings(weighting="envelope").weighting_for(operational=False) == "envelope"
    assert Settings(weighting="noise").weighting_for(operational=True) == "noise"


def test_noise_resampling_is_refused_with_envelope_weighting():
    with pytest.raises(SettingsError, match="resample"):
        Settings(resample="noise", weighting="envelope")
    Settings(resample="noise")  # auto weighting: allowed
