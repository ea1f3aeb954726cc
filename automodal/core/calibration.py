"""FE model calibration against a test data model, with damping equalization and bootstrap.

The deviation of an FE model from the test is measured between the logarithms of the two
FRFs at the measured lines, each FE mode given the damping of its test mode
(:mod:`automodal.core.damping_equalization`):

    eps_k = w_k log( H_FE(w_k; theta) / H_X(w_k) )       (per FRF entry, complex log),

whose real part is the log-magnitude error and whose imaginary part the phase error. The
weight ``w_k = |H_X(w_k)| / sigma_k`` is the FRF's signal-to-noise ratio: the standard
deviation of ``log H`` is ``sigma / |H|`` for a small noise of standard deviation ``sigma``,
so the weighted sum of squares ``sum |eps_k|^2`` is the log-FRF misfit in units of the
noise, and lines where the FRF drowns in noise (anti-resonances) count little.

The calibration minimizes ``sum |eps|^2`` over the bounded parameters by a trust-region
Gauss-Newton (Levenberg-Marquardt-like) method (``scipy.optimize.least_squares``). Its
minimum then starts the same calibration on bootstrap datasets: each is the test data model
plus the measured residuals, each line's residual turned by a random phase (a wild
bootstrap, which keeps every line's noise level and the correlation between the entries of
a line); each dataset's test data model is fitted again (its poles refined by weighted
least squares, :func:`automodal.core.refine.refine_poles`, then its residues), and the
parameters calibrated to it. The spread of the replicates' parameters is the parameters'
uncertainty, and their FE models' modes bound the predictions (Vakilzadeh, Yaghoubi,
Johansson and Abrahamsson).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
import scipy.optimize

from automodal.core import parallel
from automodal.core.damping_equalization import TestModel, fe_damping, fit_test_model
from automodal.core.fe_model import ParametrizedModel, modal_frf, undamped_modes
from automodal.core.refine import refine_poles

TOLERANCE = 1e-10
"""Relative tolerance of the least-squares solver on the cost and on the parameters."""

MAX_EVALUATIONS_PER_PARAMETER = 100
"""Residual evaluations at most per parameter (a calibration from 50 % off took about 10)."""


@dataclass(frozen=True)
class CalibrationProblem:
    """What the deviation needs besides the parameters and the test data model.

    Attributes
    ----------
    model : ParametrizedModel
    omega : ndarray, shape (N,)
        The measured lines (rad/s).
    weights : ndarray, shape (N, ny, nu)
        The signal-to-noise ratio of each line and entry (:func:`snr_weights`).
    power : int
        0 receptance, 1 mobility, 2 accelerance.
    equalization : str
        ``"paired"``, ``"common"`` or ``"none"`` (:mod:`automodal.core.damping_equalization`).
    fallback_damping : float
        Damping ratio of FE modes no test mode sets.
    common_damping : float or None
        ``zeta0`` of the ``"common"`` scheme.
    """

    model: ParametrizedModel
    omega: np.ndarray
    weights: np.ndarray
    power: int
    equalization: str = "paired"
    fallback_damping: float = 0.01
    common_damping: float | None = None


@dataclass(frozen=True)
class CalibrationFit:
    """One calibration: the parameters at the minimum and how it was reached."""

    theta: np.ndarray
    cost: float
    """``sum |eps|^2`` at ``theta``."""
    evaluations: int
    converged: bool
    message: str


@dataclass(frozen=True)
class BootstrapCalibration:
    """The calibrations on the bootstrap datasets.

    Attributes
    ----------
    theta : ndarray, shape (B, p)
        Each replicate's parameters.
    fe_frequency_hz : ndarray, shape (B, m_fe)
        Each replicate's FE natural frequencies (all FE modes, by frequency).
    test_frequency_hz : ndarray, shape (B, m)
        Each replicate's test data model frequencies (in the nominal model's pole order).
    converged : ndarray of bool, shape (B,)
    """

    theta: np.ndarray
    fe_frequency_hz: np.ndarray
    test_frequency_hz: np.ndarray
    converged: np.ndarray


def snr_weights(H_model: np.ndarray, variance: np.ndarray) -> np.ndarray:
    """``|H| / sigma`` per line and entry (0 where the variance is not positive)."""
    sigma = np.sqrt(np.asarray(variance, dtype=float))
    ok = sigma > 0
    return np.where(ok, np.abs(H_model) / np.where(ok, sigma, 1.0), 0.0)


def target_frf(problem: CalibrationProblem, test: TestModel) -> np.ndarray:
    """The test data model's FRF the FE model is compared with (damping moved to ``zeta0``
    under the ``"common"`` scheme)."""
    common = problem.common_damping if problem.equalization == "common" else None
    return test.frf(problem.omega, common)


def fe_frf(problem: CalibrationProblem, theta: np.ndarray, test: TestModel) -> np.ndarray:
    """The FE model's FRF at ``theta`` with its damping equalized to ``test``."""
    modes = undamped_modes(problem.model, theta)
    zeta = fe_damping(modes, test, problem.equalization, problem.fallback_damping,
                      problem.common_damping)
    return modal_frf(modes, zeta, problem.omega, problem.power)


def log_deviation(H_fe: np.ndarray, H_x: np.ndarray) -> np.ndarray:
    """``log(H_fe / H_x)`` (complex), 0 where either is zero or not finite."""
    with np.errstate(divide="ignore", invalid="ignore"):
        eps = np.log(H_fe / H_x)
    return np.where(np.isfinite(eps), eps, 0.0)


def residuals(
    problem: CalibrationProblem, theta: np.ndarray, test: TestModel, H_x: np.ndarray
) -> np.ndarray:
    """The weighted log deviations ``eps`` as one real vector (real parts, then imaginary)."""
    eps = problem.weights * log_deviation(fe_frf(problem, theta, test), H_x)
    return np.concatenate([eps.real.ravel(), eps.imag.ravel()])


def deviation(problem: CalibrationProblem, theta: np.ndarray, test: TestModel) -> float:
    """The weighted mean squared log deviation ``sum |eps|^2 / sum w^2`` (neper^2; its root
    is the typical relative FRF error)."""
    r = residuals(problem, theta, test, target_frf(problem, test))
    return float(np.sum(r**2) / max(float(np.sum(problem.weights**2)), np.finfo(float).tiny))


def calibrate(
    problem: CalibrationProblem, test: TestModel, theta0: np.ndarray
) -> CalibrationFit:
    """Minimize the deviation from ``theta0`` within the bounds.

    Parameters
    ----------
    problem : CalibrationProblem
    test : TestModel
        The test data model to calibrate against.
    theta0 : ndarray, shape (p,)
        The start (clipped into the bounds).

    Returns
    -------
    CalibrationFit
    """
    m = problem.model
    H_x = target_frf(problem, test)
    x0 = np.clip(np.asarray(theta0, dtype=float), m.lower, m.upper)

    def fun(theta: np.ndarray) -> np.ndarray:
        return residuals(problem, theta, test, H_x)

    sol = scipy.optimize.least_squares(
        fun, x0, bounds=(m.lower, m.upper), method="trf", x_scale="jac",
        ftol=TOLERANCE, xtol=TOLERANCE, gtol=TOLERANCE,
        max_nfev=MAX_EVALUATIONS_PER_PARAMETER * m.n_parameters)
    return CalibrationFit(theta=np.asarray(sol.x, dtype=float), cost=float(2.0 * sol.cost),
                          evaluations=int(sol.nfev), converged=bool(sol.status > 0),
                          message=str(sol.message))


def calibrate_in_two_stages(
    problem: CalibrationProblem, test: TestModel, theta0: np.ndarray
) -> CalibrationFit:
    """:func:`calibrate` with the ``"common"`` scheme first, then ``problem``'s own scheme
    from that solution (a ``"common"`` problem is solved once).

    Every mode of both models at one damping ratio gives the smoothest deviation, but its
    minimum is biased (0.7 % on the 6-DOF chain with 1 % noise: the identified damping, and
    with it the resonances' sharpness, is thrown away); the ``"paired"`` minimum is not
    (0.007 %) but, from starts 60-70 % off, mispaired modes sent 5 of 40 calibrations
    astray (``benchmarks/results_calibrate.md``). The first stage brings the start within
    the second's reach.
    """
    if problem.equalization == "common" or problem.common_damping is None:
        return calibrate(problem, test, theta0)
    first = calibrate(replace(problem, equalization="common"), test, theta0)
    second = calibrate(problem, test, first.theta)
    return replace(second, evaluations=first.evaluations + second.evaluations)


def wild_replicate(H: np.ndarray, H_model: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A bootstrap dataset: ``H_model`` plus the residuals ``H - H_model``, each line's turned
    by one random phase (the same for every entry of the line)."""
    phase = np.exp(2j * np.pi * rng.random(H.shape[0]))
    return H_model + phase[:, None, None] * (H - H_model)


def refit_test_model(
    omega: np.ndarray, H: np.ndarray, variance: np.ndarray, test: TestModel
) -> TestModel:
    """The test data model of ``H`` (the measured data, or a bootstrap dataset):
    ``test``'s poles refined on ``H`` (weighted least squares), then the residues for them.
    The calibration on the measured data and those on the bootstrap datasets use this one
    estimator, so that the replicates spread around the calibrated value (with the
    identification's poles as they were, intervals missed the truth on a quarter of the
    noise seeds)."""
    poles = refine_poles(omega, H, variance, test.poles, np.zeros(0, complex)).poles
    return fit_test_model(omega, H, poles, test.power, variance)


def bootstrap_calibrations(
    problem: CalibrationProblem,
    H: np.ndarray,
    variance: np.ndarray,
    test: TestModel,
    theta_hat: np.ndarray,
    n_bootstrap: int,
    seed: int,
    jobs: int | None = None,
    progress: Callable[[int], None] | None = None,
) -> BootstrapCalibration:
    """Calibrate on ``n_bootstrap`` bootstrap datasets, each started from ``theta_hat``.

    Parameters
    ----------
    problem : CalibrationProblem
    H : ndarray, shape (N, ny, nu)
        The measured FRF at ``problem.omega``.
    variance : ndarray, shape (N, ny, nu)
        Its noise variance.
    test : TestModel
        The test data model of ``H``.
    theta_hat : ndarray, shape (p,)
        The calibration on ``H``.
    n_bootstrap : int
    seed : int
        Replicate ``b`` draws from its own stream of ``SeedSequence(seed)``, so the result
        does not depend on ``jobs``.
    jobs : int or None
        Worker threads (None: all cores).
    progress : callable, optional
        Called with 1 as each replicate finishes, in order.
    """
    H_model = test.frf(problem.omega)
    streams = np.random.SeedSequence(seed).spawn(n_bootstrap)

    def one(b: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
        H_b = wild_replicate(H, H_model, np.random.default_rng(streams[b]))
        test_b = refit_test_model(problem.omega, H_b, variance, test)
        fit = calibrate(problem, test_b, theta_hat)
        fe = undamped_modes(problem.model, fit.theta)
        return fit.theta, fe.frequency_hz, test_b.frequency_hz, fit.converged

    n_jobs = parallel.worker_count(jobs, n_bootstrap)
    out = []
    with parallel.thread_map(n_jobs) as pmap:
        for item in pmap(one, range(n_bootstrap)):
            out.append(item)
            if progress:
                progress(1)
    p = problem.model.n_parameters
    if not out:
        return BootstrapCalibration(np.zeros((0, p)), np.zeros((0, 0)), np.zeros((0, 0)),
                                    np.zeros(0, bool))
    return BootstrapCalibration(
        theta=np.array([o[0] for o in out]).reshape(-1, p),
        fe_frequency_hz=np.array([o[1] for o in out]),
        test_frequency_hz=np.array([o[2] for o in out]),
        converged=np.array([o[3] for o in out], dtype=bool))
