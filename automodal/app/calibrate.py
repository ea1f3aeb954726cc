"""``automodal calibrate``: an FE model calibrated to measured FRFs, with its uncertainty.

One run: read the FRF file and the model file (:mod:`automodal.io.model_file`), identify the
test's modes (the pipeline), build the test data model (the physical modes' poles with
noise-weighted residues), calibrate the parameters from their nominal values with damping
equalization, then again on bootstrap datasets from that solution
(:mod:`automodal.core.calibration`), and write the result (``docs/calibrate.md``).
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from automodal import __version__
from automodal.core import calibration as cal
from automodal.core.damping_equalization import TestModel, fit_test_model, pair_modes
from automodal.core.fe_model import ParametrizedModel, undamped_modes
from automodal.core.modal import mac
from automodal.core.parallel import blas_threads
from automodal.errors import InputError
from automodal.frfdata import FRFData
from automodal.progress import ProgressCallback, counter

RESULT_FORMAT = "automodal-calibration"
RESULT_VERSION = 1


@dataclass(frozen=True)
class CalibrationSettings:
    """The choices of a calibration run, checked when made.

    Attributes
    ----------
    seed : int
        Seed of the identification's and the calibration's bootstrap (>= 0).
    n_bootstrap : int
        Bootstrap datasets calibrated (>= 2); the identification uses as many replicates.
    jobs : int or None
        Worker threads (None: all cores when it pays); never changes the result.
    band_hz : (float, float) or None
        The band to identify and calibrate in (default: the file's).
    equalization : str
        ``"paired"`` (default), ``"common"`` or ``"none"``
        (:mod:`automodal.core.damping_equalization`).
    common_damping : float
        ``zeta0`` of ``"common"``.
    """

    seed: int = 0
    n_bootstrap: int = 100
    jobs: int | None = None
    band_hz: tuple[float, float] | None = None
    equalization: str = "paired"
    common_damping: float = 0.05

    def __post_init__(self) -> None:
        from automodal.core.damping_equalization import EQUALIZATIONS

        if not (isinstance(self.seed, int) and self.seed >= 0):
            raise InputError(f"seed must be an integer >= 0, got {self.seed!r}")
        if not (isinstance(self.n_bootstrap, int) and self.n_bootstrap >= 2):
            raise InputError(f"the bootstrap needs at least 2 datasets, got {self.n_bootstrap!r}")
        if self.jobs is not None and not (isinstance(self.jobs, int) and self.jobs >= 1):
            raise InputError(f"jobs must be an integer >= 1, got {self.jobs!r}")
        if self.equalization not in EQUALIZATIONS:
            raise InputError(f"equalization must be one of {', '.join(EQUALIZATIONS)}")
        if not 0 < self.common_damping < 1:
            raise InputError("the common damping ratio must be in (0, 1)")

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form (``jobs`` left out: it never changes the result)."""
        return {"seed": self.seed, "n_bootstrap": self.n_bootstrap,
                "band_hz": None if self.band_hz is None else list(self.band_hz),
                "equalization": self.equalization, "common_damping": self.common_damping}


@dataclass
class CalibrationOutcome:
    """What one calibration run found (``to_dict`` is the result file's content).

    Attributes
    ----------
    result : dict
        The result document (``docs/calibrate.md``).
    frequency_hz : ndarray, shape (N,)
        The calibrated lines.
    measured, test_model, fe_before, fe_after : ndarray, shape (N, ny, nu)
        The measured FRF, the test data model's, and the FE model's at the nominal and the
        calibrated parameters (damping equalized), for the figures.
    replicate_theta : ndarray, shape (B, p)
        The parameters of the bootstrap datasets whose calibration converged (all of them
        when fewer than two did), the ones the intervals come from.
    """

    result: dict[str, Any]
    frequency_hz: np.ndarray
    measured: np.ndarray
    test_model: np.ndarray
    fe_before: np.ndarray
    fe_after: np.ndarray
    replicate_theta: np.ndarray
    names: list[str] = field(default_factory=list)


def check_channels(data: FRFData, model: ParametrizedModel, model_source: str) -> None:
    """Refuse a model whose ``/outputs/dof`` and ``/inputs/dof`` do not match the FRF file's
    channels, and output-only data."""
    if data.output_only:
        raise InputError("output-only (operational) data have no FRFs to calibrate against",
                         data.source)
    ny, nu = data.frf.shape[1:]
    if (model.outputs.size, model.inputs.size) != (ny, nu):
        raise InputError(
            f"/outputs/dof and /inputs/dof name {model.outputs.size} output(s) and"
            f" {model.inputs.size} input(s), but the FRF file has {ny} output(s) and {nu}"
            " input(s): give one model DOF per FRF channel, in the FRF file's order",
            model_source)


def calibrate_file(
    frf_path: str | os.PathLike[str],
    model_path: str | os.PathLike[str],
    settings: CalibrationSettings,
    progress: ProgressCallback | None = None,
) -> CalibrationOutcome:
    """Read both files and calibrate (:func:`calibrate_data`)."""
    from automodal.app.run import read_input
    from automodal.io.model_file import read_model

    model = read_model(model_path)
    data = read_input(frf_path, progress=progress)
    check_channels(data, model, os.fspath(model_path))
    return calibrate_data(data, model, settings, progress)


def _identified_poles(data: FRFData, settings: CalibrationSettings,
                      progress: ProgressCallback | None) -> tuple[np.ndarray, Any]:
    """The physical modes' poles as they are in the data, and the pipeline's result."""
    from automodal.core.synthesis import modal_poles
    from automodal.pipeline import identify, pole_map_of
    from automodal.settings import Settings

    result = identify(data, Settings(band_hz=settings.band_hz, n_bootstrap=settings.n_bootstrap,
                                     seed=settings.seed, jobs=settings.jobs), progress)
    phys = [m for m in result.physical_modes
            if np.isfinite(m.frequency_hz) and np.isfinite(m.damping_ratio)]
    if not phys:
        raise InputError("no physical mode was identified in the band: there is nothing to"
                         " calibrate against (try --band)", data.source)
    lam = modal_poles(np.array([m.frequency_hz for m in phys]),
                      np.array([m.damping_ratio for m in phys]))
    return pole_map_of(data).to_model(lam), result


def calibrate_data(
    data: FRFData,
    model: ParametrizedModel,
    settings: CalibrationSettings,
    progress: ProgressCallback | None = None,
) -> CalibrationOutcome:
    """Calibrate ``model`` to ``data`` (the whole run but the files).

    Parameters
    ----------
    data : FRFData
    model : ParametrizedModel
        Its outputs and inputs must match ``data``'s channels (:func:`check_channels`).
    settings : CalibrationSettings
    progress : callable, optional
        Called with a :class:`~automodal.progress.Progress` as each stage starts (the
        identification's, then ``"calibration"``) and as the replicates of each bootstrap
        finish.

    Returns
    -------
    CalibrationOutcome
    """
    from automodal.core.noise import averages_from_attributes, estimate_noise
    from automodal.quantities import quantity_power

    t0 = time.perf_counter()
    poles, identified = _identified_poles(data, settings, progress)
    lo, hi = identified.band_hz
    lines = (data.frequency >= lo) & (data.frequency <= hi) & (data.frequency > 0)
    f = data.frequency[lines]
    omega, H = 2.0 * np.pi * f, data.frf[lines]
    noise = estimate_noise(
        H, coherence=None if data.coherence is None else data.coherence[lines],
        records=None if data.records is None else data.records[:, lines],
        n_averages=averages_from_attributes(data.attributes))
    power = quantity_power(data.quantity)
    with blas_threads(1):
        test = cal.refit_test_model(omega, H, noise.variance,
                                    fit_test_model(omega, H, poles, power, noise.variance))
        fallback = (model.damping if model.damping is not None
                    else float(np.median(test.damping_ratio)))
        problem = cal.CalibrationProblem(
            model=model, omega=omega, weights=cal.snr_weights(test.frf(omega), noise.variance),
            power=power, equalization=settings.equalization, fallback_damping=fallback,
            common_damping=settings.common_damping)
        nominal = np.ones(model.n_parameters)
        fit = cal.calibrate_in_two_stages(problem, test, nominal)
        boot = cal.bootstrap_calibrations(problem, H, noise.variance, test, fit.theta,
                                          settings.n_bootstrap, settings.seed, settings.jobs,
                                          counter(progress, "calibration", settings.n_bootstrap))
        result = _result(problem, test, fit, boot, nominal, identified, settings, data)
        fe_before = cal.fe_frf(problem, nominal, test)
        fe_after = cal.fe_frf(problem, fit.theta, test)
    result["runtime_s"] = time.perf_counter() - t0
    return CalibrationOutcome(result=result, frequency_hz=f, measured=H,
                              test_model=cal.target_frf(problem, test), fe_before=fe_before,
                              fe_after=fe_after, replicate_theta=_interval_datasets(boot),
                              names=list(model.names))


def _interval(samples: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Standard deviation and 95 % percentile interval over axis 0."""
    std = samples.std(axis=0, ddof=1) if samples.shape[0] > 1 else np.full(samples.shape[1:],
                                                                            np.nan)
    lo, hi = np.percentile(samples, [2.5, 97.5], axis=0)
    return std, lo, hi


def _interval_datasets(boot: cal.BootstrapCalibration,
                       values: np.ndarray | None = None) -> np.ndarray:
    """``values`` of the bootstrap datasets (default their parameters) the intervals come
    from: those whose calibration converged, or all of them when fewer than two did."""
    values = boot.theta if values is None else values
    ok = boot.converged
    return values[ok] if ok.sum() >= 2 else values


def _result(problem: cal.CalibrationProblem, test: TestModel, fit: cal.CalibrationFit,
            boot: cal.BootstrapCalibration, nominal: np.ndarray, identified: Any,
            settings: CalibrationSettings, data: FRFData) -> dict[str, Any]:
    """The result document."""
    model = problem.model
    ok = boot.converged
    std, lo, hi = _interval(_interval_datasets(boot))
    parameters = [
        {"name": name, "value": float(fit.theta[i]), "std": float(std[i]),
         "ci95": [float(lo[i]), float(hi[i])], "lower": float(model.lower[i]),
         "upper": float(model.upper[i]),
         "at_bound": bool(np.isclose(fit.theta[i], model.lower[i], rtol=1e-6)
                          or np.isclose(fit.theta[i], model.upper[i], rtol=1e-6))}
        for i, name in enumerate(model.names)]
    before_modes = undamped_modes(model, nominal)
    after_modes = undamped_modes(model, fit.theta)
    pairs = dict(pair_modes(after_modes, test))
    macs = mac(test.residue_vectors(), after_modes.residue_vectors())
    order = np.argsort(test.frequency_hz)
    f_std, f_lo, f_hi = _interval(_interval_datasets(boot, boot.fe_frequency_hz))
    meas_b = np.sort(boot.test_frequency_hz, axis=1)
    m_std, m_lo, m_hi = _interval(meas_b)
    modes = []
    for rank, i in enumerate(order):
        j = pairs.get(int(i))
        entry: dict[str, Any] = {
            "mode": rank + 1,
            "measured_frequency_hz": float(test.frequency_hz[i]),
            "measured_frequency_std_hz": float(m_std[rank]),
            "measured_frequency_ci95_hz": [float(m_lo[rank]), float(m_hi[rank])],
            "measured_damping_ratio": float(test.damping_ratio[i]),
            "fe_mode": None, "nominal_frequency_hz": None, "predicted_frequency_hz": None,
            "predicted_frequency_std_hz": None, "predicted_frequency_ci95_hz": None,
            "relative_error_before": None, "relative_error_after": None, "mac": None}
        if j is not None:
            f_x = float(test.frequency_hz[i])
            entry.update({
                "fe_mode": int(j) + 1,
                "nominal_frequency_hz": float(before_modes.frequency_hz[j]),
                "predicted_frequency_hz": float(after_modes.frequency_hz[j]),
                "predicted_frequency_std_hz": float(f_std[j]),
                "predicted_frequency_ci95_hz": [float(f_lo[j]), float(f_hi[j])],
                "relative_error_before": float(before_modes.frequency_hz[j] / f_x - 1),
                "relative_error_after": float(after_modes.frequency_hz[j] / f_x - 1),
                "mac": float(macs[i, j])})
        modes.append(entry)
    dev_before = cal.deviation(problem, nominal, test)
    dev_after = cal.deviation(problem, fit.theta, test)
    warnings = [f"identification: {w}" for w in identified.warnings]
    if not fit.converged:
        warnings.append(f"the calibration did not converge: {fit.message}")
    if (~ok).any():
        warnings.append(f"{int((~ok).sum())} of {ok.size} bootstrap calibrations did not"
                        " converge (left out of the statistics)")
    warnings += [f"parameter {p['name']} ended at its bound {p['value']:g}: widen the bounds"
                 " or question the model" for p in parameters if p["at_bound"]]
    outside = [p["name"] for p in parameters
               if not p["ci95"][0] <= p["value"] <= p["ci95"][1]]
    if outside:
        warnings.append(
            f"the calibrated {', '.join(outside)} lie(s) outside the bootstrap's 95 % interval:"
            " the bootstrap datasets (test data model plus the residuals) differ"
            " systematically from the data, a sign that the model class cannot explain the"
            " test; the intervals measure the noise only, not that error")
    return {
        "format": RESULT_FORMAT, "version": RESULT_VERSION, "automodal_version": __version__,
        "source": data.source, "quantity": data.quantity,
        "band_hz": [float(problem.omega[0] / (2 * np.pi)),
                    float(problem.omega[-1] / (2 * np.pi))],
        "n_lines": int(problem.omega.size),
        "settings": settings.to_dict(),
        "parameters": parameters,
        "modes": modes,
        "deviation": {"before": dev_before, "after": dev_after,
                      "rms_log_before": float(np.sqrt(dev_before)),
                      "rms_log_after": float(np.sqrt(dev_after))},
        "calibration": {"converged": fit.converged, "evaluations": fit.evaluations,
                        "message": fit.message,
                        "fallback_damping": problem.fallback_damping},
        "bootstrap": {"n": int(ok.size), "converged": int(ok.sum()),
                      "parameters": boot.theta.tolist()},
        "warnings": warnings,
    }


def write_result(path: str | os.PathLike[str], result: dict[str, Any]) -> Path:
    """Write the result as JSON, atomically (whole or not at all)."""
    from automodal.io.atomic import atomic_path
    from automodal.io.json_safe import json_safe

    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as fh:
            json.dump(json_safe(result), fh, indent=2, ensure_ascii=False, allow_nan=False)
            fh.write("\n")
    return Path(path)
