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
    and after calibration (damping equalized).

    The measured FRF is a wide grey band under the thin black test data model, and the
    calibrated FE model is dashed, so that a model lying on the data leaves both visible.
    At most :data:`MAX_PANELS` entries are drawn; the title says when more exist.
    """
    from matplotlib.figure import Figure

    from automodal.app.plots import magnitude_label

    _, ny, nu = outcome.measured.shape
    every = [(i, j) for i in range(ny) for j in range(nu)]
    entries = every[:MAX_PANELS]
    cols = min(3, len(entries))
    rows = -(-len(entries) // cols)
    fig = Figure(figsize=(4.2 * cols, 2.6 * rows + 0.6), layout="constrained")
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False)).ravel()
    f = outcome.frequency_hz
    curves = [(outcome.measured, "measured", dict(color="0.55", lw=3.0, alpha=0.5)),
              (outcome.test_model, "test data model", dict(color="k", lw=0.9)),
              (outcome.fe_before, "FE nominal", dict(color="tab:red", lw=0.9, ls=":")),
              (outcome.fe_after, "FE calibrated", dict(color="tab:blue", lw=1.3,
                                                       ls=(0, (5, 3))))]
    ylabel = magnitude_label(str(outcome.result.get("quantity", "")))
    for k, (ax, (i, j)) in enumerate(zip(axes, entries)):
        for H, label, style in curves:
            ax.semilogy(f, np.abs(H[:, i, j]), label=label, **style)
        ax.set_title(f"output {i + 1} / input {j + 1}", fontsize=9)
        ax.set_xlabel("frequency (Hz)", fontsize=8)
        if k % cols == 0:
            ax.set_ylabel(ylabel, fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in axes[len(entries):]:
        ax.set_visible(False)
    axes[0].legend(fontsize=7)
    shown = "" if len(every) == len(entries) else f" ({len(entries)} of {len(every)} entries)"
    fig.suptitle("FRF magnitude: measured, test data model, FE before and after calibration"
                 + shown)
    return fig


def parameter_distributions(outcome: CalibrationOutcome) -> Figure:
    """A histogram of each parameter over the bootstrap datasets, as its change from the
    calibrated value in percent (readable ticks however narrow the spread), with the 95 %
    interval; each title gives the calibrated value and the interval itself."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator, ScalarFormatter

    params = outcome.result["parameters"]
    n = len(params)
    cols = min(4, n)
    rows = -(-n // cols)
    fig = Figure(figsize=(3.4 * cols, 2.6 * rows + 0.5), layout="constrained")
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False)).ravel()
    theta = outcome.replicate_theta
    for k, (ax, p) in enumerate(zip(axes, params)):
        value = float(p["value"])
        rel = 100.0 * (theta[:, k] / value - 1.0)
        ax.hist(rel, bins=min(30, max(5, theta.shape[0] // 4)), color="tab:blue", alpha=0.7)
        ax.axvline(0.0, color="k", lw=1.2)
        lo, hi = (float(e) for e in p["ci95"])
        for edge in (lo, hi):
            ax.axvline(100.0 * (edge / value - 1.0), color="tab:red", lw=0.9, ls="--")
        ax.set_title(f"{p['name']} = {value:.5g}  (95 %: {lo:.5g} to {hi:.5g})", fontsize=8)
        ax.set_xlabel("change from the calibrated value (%)", fontsize=8)
        if k % cols == 0:
            ax.set_ylabel("bootstrap datasets", fontsize=8)
        fmt = ScalarFormatter(useOffset=False)
        fmt.set_powerlimits((-6, 6))
        ax.xaxis.set_major_formatter(fmt)
        ax.xaxis.set_major_locator(MaxNLocator(4))
        ax.tick_params(labelsize=7)
    for ax in axes[n:]:
        ax.set_visible(False)
    fig.suptitle(f"Parameters (theta, 1 = nominal) over {theta.shape[0]} bootstrap datasets: "
                 "black the calibrated value, dashed the 95 % interval")
    return fig


def save_calibration_figures(outcome: CalibrationOutcome, folder: str | os.PathLike[str]
                             ) -> list[Path]:
    """Write ``frf_overlay.png`` and ``parameters.png`` into ``folder`` (made if missing)."""
    from automodal.app.plots import save_figure

    out = Path(folder)
    return [save_figure(frf_overlay(outcome), out / "frf_overlay.png"),
            save_figure(parameter_distributions(outcome), out / "parameters.png")]
