"""The figures of a calibration: the FRF overlay and the parameters' bootstrap distributions.

Figures are :class:`~matplotlib.figure.Figure` objects (no pyplot), written atomically by
:func:`automodal.app.plots.save_figure`.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from automodal.app.calibrate import CalibrationOutcome

MAX_PANELS = 12
"""FRF entries drawn at most (the first ones, output by output)."""


def frf_overlay(outcome: CalibrationOutcome) -> Figure:
    """Magnitude of each FRF entry: measured, the test data model, and the FE model before
    and after calibration (damping equalized)."""
    from matplotlib.figure import Figure

    _, ny, nu = outcome.measured.shape
    entries = [(i, j) for i in range(ny) for j in range(nu)][:MAX_PANELS]
    cols = min(3, len(entries))
    rows = -(-len(entries) // cols)
    fig = Figure(figsize=(4.2 * cols, 2.6 * rows + 0.6), layout="constrained")
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False)).ravel()
    f = outcome.frequency_hz
    curves = [(outcome.measured, "measured", dict(color="0.6", lw=0.8)),
              (outcome.test_model, "test data model", dict(color="k", lw=1.0)),
              (outcome.fe_before, "FE nominal", dict(color="tab:red", lw=0.9, ls="--")),
              (outcome.fe_after, "FE calibrated", dict(color="tab:blue", lw=1.1))]
    for ax, (i, j) in zip(axes, entries):
        for H, label, style in curves:
            ax.semilogy(f, np.abs(H[:, i, j]), label=label, **style)
        ax.set_title(f"output {i + 1} / input {j + 1}", fontsize=9)
        ax.set_xlabel("frequency (Hz)", fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in axes[len(entries):]:
        ax.set_visible(False)
    axes[0].legend(fontsize=7)
    fig.suptitle("FRF magnitude: measured, test data model, FE before and after calibration")
    return fig


def parameter_distributions(outcome: CalibrationOutcome) -> Figure:
    """A histogram of each parameter over the bootstrap datasets, with the calibrated value
    and the 95 % interval."""
    from matplotlib.figure import Figure

    params = outcome.result["parameters"]
    n = len(params)
    cols = min(4, n)
    rows = -(-n // cols)
    fig = Figure(figsize=(3.2 * cols, 2.5 * rows + 0.5), layout="constrained")
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False)).ravel()
    theta = outcome.replicate_theta
    for k, (ax, p) in enumerate(zip(axes, params)):
        ax.hist(theta[:, k], bins=min(30, max(5, theta.shape[0] // 4)), color="tab:blue",
                alpha=0.7)
        ax.axvline(p["value"], color="k", lw=1.2, label="calibrated")
        for edge in p["ci95"]:
            ax.axvline(edge, color="tab:red", lw=0.9, ls="--")
        ax.set_title(p["name"], fontsize=9)
        ax.set_xlabel("theta (1 = nominal)", fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in axes[n:]:
        ax.set_visible(False)
    fig.suptitle("Parameters over the bootstrap datasets (dashed: 95 % interval)")
    return fig


def save_calibration_figures(outcome: CalibrationOutcome, folder: str | os.PathLike[str]
                             ) -> list[Path]:
    """Write ``frf_overlay.png`` and ``parameters.png`` into ``folder`` (made if missing)."""
    from automodal.app.plots import save_figure

    out = Path(folder)
    return [save_figure(frf_overlay(outcome), out / "frf_overlay.png"),
            save_figure(parameter_distributions(outcome), out / "parameters.png")]
