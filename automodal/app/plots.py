"""Figures of an identification report: pole map, FRF fit, physicalness and mode shapes.

Pure plotting: every function takes a report (a :class:`~automodal.report_model.Report`,
or a report dict, which is checked into one by :meth:`Report.coerce
<automodal.report_model.Report.coerce>`) and, where it needs them, the arrays an HDF5
report keeps (:func:`~automodal.io.report.read_report_arrays`), and returns a
:class:`matplotlib.figure.Figure`. Nothing here reads a file or identifies anything.

Matplotlib is imported inside the functions only (so that importing :mod:`automodal`
never loads it), and figures are made as :class:`~matplotlib.figure.Figure` objects, not
through ``pyplot``: no window is opened, no global figure list grows, and saving uses
Agg (or the SVG and PDF writers) whatever the backend.

Every ``fig`` argument lets a function draw into a given figure or subfigure instead of
a new one; :func:`overview` uses this to put the four panels into one figure.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from automodal.report_model import Report, ReportMode, as_floats

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure, SubFigure

    from automodal.core.stabilization import StabilizationPoles
    from automodal.result import PoleTable
    from automodal.tracking import History

ReportLike = Report | Mapping[str, Any]
"""A :class:`~automodal.report_model.Report` or a report dict."""

__all__ = [
    "FIGURE_NAMES",
    "automac",
    "frf_fit",
    "mode_shapes",
    "overview",
    "physicalness_bars",
    "pole_map",
    "save_figure",
    "save_figures",
    "stabilization_diagram",
    "trend",
]

FIGURE_NAMES = ("overview", "stabilization", "poles", "frf_fit", "physicalness", "mode_shapes",
                "automac")
"""Stems of the files :func:`save_figures` writes (each only when its data exist)."""

MAX_FRF_CHANNELS = 4
"""Most FRF channels (output/input pairs) :func:`frf_fit` draws."""

OVERVIEW_SHAPE_COLUMNS = 6
"""Mode-shape panels per row in :func:`overview`."""

POLE_MAP_HEADROOM = 1.3
"""Height of the pole map over the number of replicates: the room above holds the labels."""

TRASHBOX_COLOR = "0.78"
PHYSICAL_COLOR = "tab:blue"
NON_PHYSICAL_COLOR = "0.55"
_QUANTITY_FRF = {
    "displacement": ("receptance", "m/N"),
    "velocity": ("mobility", "(m/s)/N"),
    "acceleration": ("accelerance", "(m/s²)/N"),
}
_QUANTITY_UNIT = {"displacement": "m", "velocity": "m/s", "acceleration": "m/s²"}
LABEL_FONT = 7.0
"""Font size (points) of the mode labels above the pole maps."""
_DIRECTIONS = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}


# ------------------------------------------------------------------------------ panels


def pole_map(
    report: ReportLike,
    poles: PoleTable | Mapping[str, np.ndarray],
    frf: Mapping[str, np.ndarray] | Sequence[np.ndarray] | None = None,
    *,
    fig: Figure | SubFigure | None = None,
) -> Figure | SubFigure:
    """Stabilization-diagram-style map of every bootstrap pole.

    Parameters
    ----------
    report : Report or dict
        The report (its ``modes``, ``input.band_hz`` and ``summary`` are used).
    poles : PoleTable or dict
        Every bootstrap pole: ``frequency_hz``, ``cluster`` (``-1`` for the Trashbox) and
        ``replicate`` (attributes or keys, as in ``read_report_arrays(path)["poles"]``).
    frf : dict or sequence, optional
        ``{"frequency": f, "measured": H, ...}`` or ``(f, H, ...)``: the summed FRF
        magnitude is drawn behind the poles on a logarithmic second y axis.
    fig : Figure or SubFigure, optional
        Where to draw; default a new figure.

    Returns
    -------
    Figure or SubFigure
        One axes (x: frequency in Hz, y: bootstrap replicate), plus its twin when the
        FRF is drawn. Trashbox poles are light grey (``gid="trashbox"``); each cluster has
        its own colour (``gid="cluster-<id>"``), physical clusters large and labelled with
        their frequencies.
    """
    report = Report.coerce(report)
    fig = _canvas(fig, (11.0, 4.5))
    ax = fig.add_subplot()
    cols = _pole_columns(poles)
    freq, cluster, replicate = cols["frequency_hz"], cols["cluster"], cols["replicate"]
    by_cluster = _clusters(report)
    trash = cluster < 0
    ax.scatter(freq[trash], replicate[trash], s=4, c=TRASHBOX_COLOR, marker=".",
               linewidths=0, label="Trashbox", gid="trashbox", zorder=1)
    colors = _cluster_colors(by_cluster, np.unique(cluster[~trash]))
    for c, color in colors.items():
        sel = cluster == c
        physical = by_cluster.get(c, _NO_CLUSTER).physical
        style = (
            {"s": 14, "marker": "o", "linewidths": 0, "zorder": 3}
            if physical
            else {"s": 9, "marker": "x", "linewidths": 0.7, "alpha": 0.8, "zorder": 2}
        )
        ax.scatter(freq[sel], replicate[sel], c=[color], gid=f"cluster-{c}", **style)
    n_rep = int(replicate.max()) + 1 if replicate.size else 1
    ax.set_ylim(-0.5, POLE_MAP_HEADROOM * n_rep)
    ax.set_xlim(*_band(report, freq))
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("bootstrap replicate")
    modes = report.physical_modes
    _label_modes(ax, fig, modes, [colors.get(m.cluster, PHYSICAL_COLOR) for m in modes])
    handles = _pole_legend_handles()
    parts = _frf_parts(frf)
    if parts is not None:
        handles.append(_draw_frf_sum(ax, parts[0], parts[1], _operational(report)))
    _top_legend(ax, fig, handles)
    summary = report.summary
    n_trash = int(np.count_nonzero(trash))
    fig.suptitle(
        f"Bootstrap poles: {summary.n_clusters} clusters,"
        f" {summary.n_physical} physical, {n_trash} poles in the Trashbox",
        fontsize=10,
    )
    return fig


def stabilization_diagram(
    report: ReportLike,
    stabilization: StabilizationPoles | Mapping[str, np.ndarray],
    frf: Mapping[str, np.ndarray] | Sequence[np.ndarray] | None = None,
    *,
    fig: Figure | SubFigure | None = None,
) -> Figure | SubFigure:
    """The stabilization diagram: the poles of the order scan's models against their order.

    Parameters
    ----------
    report : Report or dict
        The report (its physical modes, band and ``settings.orders``).
    stabilization : StabilizationPoles or dict
        ``order``, ``frequency_hz``, ``damping_ratio`` and ``stability`` (bits: 1
        frequency, 2 damping, 4 MAC stable against the previous order; see
        :mod:`automodal.core.stabilization` for the tolerances), as
        ``read_report_arrays(path)["stabilization"]`` gives them.
    frf : dict or sequence, optional
        The FRFs: their magnitude summed over channels is drawn behind on a log y axis.
    fig : Figure or SubFigure, optional
        Where to draw; default a new figure.

    Returns
    -------
    Figure or SubFigure
        One axes (x: frequency in Hz, y: model order) with one marker style per stability
        class (``gid`` ``"stable"``: frequency, damping and MAC; ``"stable-f-mac"``;
        ``"stable-f"``; ``"new"``: none), the reported physical modes as labelled dotted
        lines and the order the replicates used (``settings.orders.reference``) dashed.
    """
    from automodal.core import stabilization as st

    report = Report.coerce(report)
    fig = _canvas(fig, (11.0, 5.0))
    ax = fig.add_subplot()
    cols = _columns(stabilization, {"order": int, "frequency_hz": float, "stability": int})
    order, freq, flags = cols["order"], cols["frequency_hz"], cols["stability"]
    f_ok = (flags & st.STABLE_FREQUENCY) > 0
    mac_ok = (flags & st.STABLE_SHAPE) > 0
    classes = [
        ("new", ~f_ok, {"marker": ".", "s": 6, "c": "0.7", "linewidths": 0}),
        ("stable-f", f_ok & ~mac_ok, {"marker": "x", "s": 12, "c": "tab:orange",
                                      "linewidths": 0.7}),
        ("stable-f-mac", f_ok & mac_ok & (flags != st.STABLE_ALL),
         {"marker": "+", "s": 22, "c": "tab:blue", "linewidths": 0.8}),
        ("stable", flags == st.STABLE_ALL, {"marker": "o", "s": 14, "c": "tab:green",
                                            "linewidths": 0, "zorder": 3}),
    ]
    handles = []
    from matplotlib.lines import Line2D

    labels = {"new": "new or unstable", "stable-f": f"f stable ({_pct(st.FREQUENCY_TOLERANCE)})",
              "stable-f-mac": f"f and MAC stable (MAC ≥ {st.MAC_TOLERANCE:g})",
              "stable": f"f, ζ ({_pct(st.DAMPING_TOLERANCE)}) and MAC stable"}
    for gid, sel, style in classes:
        ax.scatter(freq[sel], order[sel], gid=gid, **style)
        handles.append(Line2D([], [], ls="", marker=style["marker"], color=style["c"],
                              ms=5 if style["marker"] != "." else 6, label=labels[gid]))
    top = int(order.max()) if order.size else 2
    ax.set_ylim(0, POLE_MAP_HEADROOM * top + 2)
    ax.set_xlim(*_band(report, freq))
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("model order")
    chosen = (report.settings.values.get("orders") or {}).get("reference")
    if isinstance(chosen, int) and chosen <= top:
        ax.axhline(chosen, color="0.4", ls="--", lw=0.8, gid="reference-order")
        handles.append(Line2D([], [], color="0.4", ls="--", lw=0.8,
                              label=f"order of the replicates ({chosen})"))
    modes = report.physical_modes
    _label_modes(ax, fig, modes, mode_colors(len(modes)))
    parts = _frf_parts(frf)
    if parts is not None:
        handles.append(_draw_frf_sum(ax, parts[0], parts[1], _operational(report)))
    _top_legend(ax, fig, handles, max_columns=3)
    n_stable = int(np.count_nonzero(flags == st.STABLE_ALL))
    fig.suptitle(
        f"Stabilization diagram: {order.size} poles of {np.unique(order).size} model orders,"
        f" {n_stable} stable; {len(modes)} physical modes (dotted)", fontsize=10)
    return fig


def automac(report: ReportLike, *, fig: Figure | SubFigure | None = None
            ) -> Figure | SubFigure:
    """The AutoMAC matrix of the physical modes: MAC of every shape with every other.

    Parameters
    ----------
    report : Report or dict
        The report (its physical modes' shapes).
    fig : Figure or SubFigure, optional
        Where to draw; default a new figure.

    Returns
    -------
    Figure or SubFigure
        One axes: the matrix as an image (``gid="automac"``, values 0 to 1), each cell
        with its value, ticks labelled with the modes' frequencies. Off-diagonal values
        near 1 mean two modes the sensors cannot tell apart.
    """
    from automodal.core.modal import mac

    report = Report.coerce(report)
    modes = report.physical_modes
    n = len(modes)
    fig = _canvas(fig, (1.2 + 0.55 * max(n, 3), 0.9 + 0.55 * max(n, 3)))
    ax = fig.add_subplot()
    if not modes:
        ax.set_axis_off()
        ax.text(0.5, 0.5, "no physical mode", ha="center", va="center", transform=ax.transAxes)
        return fig
    shapes = np.column_stack([_shape(m) for m in modes])
    matrix = np.real(mac(shapes, shapes))
    image = ax.imshow(matrix, vmin=0.0, vmax=1.0, cmap="Blues", gid="automac")
    ticks = [_mode_tag(m) for m in modes]
    ax.set_xticks(range(n), ticks, rotation=90, fontsize=7)
    ax.set_yticks(range(n), ticks, fontsize=7)
    ax.set_xlabel("mode: frequency")
    ax.set_ylabel("mode: frequency")
    if n <= 25:
        for i in range(n):
            for j in range(n):
                ax.text(j, i, f"{matrix[i, j]:.2f}", ha="center", va="center", fontsize=6,
                        color="white" if matrix[i, j] > 0.6 else "0.2", gid="mac-value")
    fig.colorbar(image, ax=ax, label="MAC", shrink=0.8)
    off = matrix[~np.eye(n, dtype=bool)]
    worst = f"; largest off-diagonal {off.max():.2f}" if off.size else ""
    channels = shapes.shape[0]
    # fewer channels than modes: the shapes cannot all be orthogonal (spatial aliasing),
    # which is the sensors' limit, not the identification's
    few = (f"\n{channels} channels for {n} modes: the shapes cannot all be orthogonal, "
           "some off-diagonal MAC is unavoidable" if channels < n else "")
    fig.suptitle(f"AutoMAC of the {n} physical modes{worst}{few}", fontsize=10)
    return fig


def frf_fit(
    report: ReportLike,
    frequency: np.ndarray,
    frf_measured: np.ndarray,
    frf_synth: np.ndarray | None,
    *,
    max_channels: int = MAX_FRF_CHANNELS,
    fig: Figure | SubFigure | None = None,
) -> Figure | SubFigure:
    """Measured FRFs against those synthesized from the physical modes.

    Parameters
    ----------
    report : Report or dict
        The report (channel names, quantity, band, physical modes).
    frequency : ndarray, shape (n,)
        Frequency lines in Hz.
    frf_measured : ndarray, shape (n, n_outputs, n_inputs)
        The measured FRFs.
    frf_synth : ndarray of the same shape, or None
        The FRFs synthesized from the physical modes; ``None`` draws the measured alone.
    max_channels : int
        Most output/input pairs drawn: those with the largest RMS magnitude.
    fig : Figure or SubFigure, optional
        Where to draw; default a new figure.

    Returns
    -------
    Figure or SubFigure
        Two axes sharing x: magnitude (logarithmic) above, phase in degrees below.
        Measured lines are solid, synthesized ones dashed in the same colour.
    """
    report = Report.coerce(report)
    fig = _canvas(fig, (10.0, 6.0))
    ax_mag, ax_ph = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    f = np.asarray(frequency, dtype=float)
    H = np.asarray(frf_measured, dtype=complex)
    S = None if frf_synth is None else np.asarray(frf_synth, dtype=complex)
    outputs, inputs = _channel_names(report, H.shape[1], H.shape[2])
    error = _fit_error(report, H, S)
    shown = _strongest_channels(H, max_channels)
    colors = mode_colors(len(shown))
    for k, (i, j) in enumerate(shown):
        color = colors[k]
        name = f"{outputs[i]}/{inputs[j]}" if H.shape[2] > 1 else outputs[i]
        if error is not None and np.isfinite(error[i, j]):
            name += f" (error {_pct_value(error[i, j])})"
        ax_mag.plot(f, np.abs(H[:, i, j]), color=color, lw=0.9, label=name, gid="measured")
        ax_ph.plot(*_wrapped_phase(f, H[:, i, j]), color=color, lw=0.9, gid="measured")
        if S is not None:
            ax_mag.plot(f, np.abs(S[:, i, j]), color=color, lw=1.3, ls="--", gid="synthesized")
            ax_ph.plot(*_wrapped_phase(f, S[:, i, j]), color=color, lw=1.3, ls="--",
                       gid="synthesized")
    ax_mag.set_yscale("log")
    for mode in report.physical_modes:
        for ax in (ax_mag, ax_ph):
            ax.axvline(mode.frequency_hz, color="0.75", lw=0.6, ls=":", zorder=0)
    ax_mag.set_ylabel(magnitude_label(report.input.quantity, _operational(report)))
    ax_ph.set_ylabel("phase (°)")
    ax_ph.set_ylim(-190, 190)
    ax_ph.set_yticks([-180, -90, 0, 90, 180])
    ax_ph.set_xlabel("frequency (Hz)")
    if f.size:
        ax_ph.set_xlim(f[0], f[-1])
    handles, _ = ax_mag.get_legend_handles_labels()
    handles += _style_handles(S is not None)
    _top_legend(ax_mag, fig, handles)
    what = ("measured (solid) and synthesized from the physical modes with upper and lower"
            " residuals (dashed)" if S is not None else "measured")
    n_all = H.shape[1] * H.shape[2]
    which = (f"all {n_all} channels" if len(shown) == n_all
             else f"{len(shown)} of {n_all} channels (the strongest)")
    overall = ""
    if error is not None and np.isfinite(error).any():
        overall = f"; median normalised error {_pct_value(float(np.nanmedian(error)))}"
    kind = "Half spectra" if _operational(report) else "FRF"
    fig.suptitle(f"{kind}, {what}\n{which}{overall}", fontsize=10)
    return fig


def physicalness_bars(
    report: ReportLike, *, fig: Figure | SubFigure | None = None
) -> Figure | SubFigure:
    """One bar per cluster at its frequency, as high as its physicalness.

    Parameters
    ----------
    report : Report or dict
        The report (its ``modes``, ``settings.min_physicalness`` and band).
    fig : Figure or SubFigure, optional
        Where to draw; default a new figure.

    Returns
    -------
    Figure or SubFigure
        One axes: bars coloured physical or not (``gid="physical"`` and
        ``"not-physical"``), the decision threshold as a dashed line (its legend counting
        the physical modes below it, which the refinement's likelihood tests hold), and the
        95 % frequency interval of each cluster as a horizontal error bar at the top of its
        bar.
    """
    report = Report.coerce(report)
    fig = _canvas(fig, (10.0, 3.5))
    ax = fig.add_subplot()
    modes = [m for m in report.modes if m.has_frequency]
    threshold = report.settings.min_physicalness
    lo, hi = _band(report, np.array([m.frequency_hz for m in modes], dtype=float))
    width = (hi - lo) / 250.0
    for physical, color in ((True, PHYSICAL_COLOR), (False, NON_PHYSICAL_COLOR)):
        group = [m for m in modes if m.physical is physical]
        f = np.array([m.frequency_hz for m in group], dtype=float)
        p = np.array([m.physicalness or 0.0 for m in group], dtype=float)
        label = "physical" if physical else "not physical"
        ax.bar(f, p, width=width, color=color, label=f"{label} ({len(group)})",
               gid=label.replace(" ", "-"))
        ax.errorbar(f, p, xerr=_ci_halfwidths(group, f), fmt="o", ms=2.5, color=color,
                    elinewidth=1.0, capsize=2, gid=f"ci-{label.replace(' ', '-')}")
    # companions, repeated pairs' second modes and weak modes the refinement's likelihood
    # tests hold are physical below the threshold (docs/report.md, `physical`): the legend
    # says how many
    below = sum(1 for m in modes if m.physical and (m.physicalness or 0.0) < threshold)
    ax.axhline(threshold, color="tab:red", ls="--", lw=1.0, label=f"threshold {threshold:g}" + (
        f" ({below} physical below it: the refinement's likelihood tests)" if below else ""))
    ax.set_xlim(lo, hi)
    ax.set_ylim(-0.04, 1.08)  # clusters of physicalness 0 stay visible as dots
    ax.axhline(0.0, color="0.6", lw=0.5, zorder=0)
    ax.set_xlabel("frequency (Hz); horizontal bars: 95 % interval")
    ax.set_ylabel("physicalness")
    if not modes:
        ax.text(0.5, 0.5, "no cluster survived", ha="center", va="center",
                transform=ax.transAxes)
    _top_legend(ax, fig, ax.get_legend_handles_labels()[0], max_columns=3)
    fig.suptitle("Physicalness of every cluster", fontsize=10)
    return fig


def mode_shapes(
    report: ReportLike,
    xyz: np.ndarray | None = None,
    *,
    max_columns: int = 4,
    fig: Figure | SubFigure | None = None,
) -> Figure | SubFigure:
    """The shape of each physical mode: bars by channel, or the displaced geometry.

    Parameters
    ----------
    report : Report or dict
        The report (its physical ``modes``, ``input.output_names``, and
        ``input.output_xyz``/``input.output_directions`` when ``xyz`` is not given).
    xyz : ndarray, shape (n_outputs, 3), optional
        Sensor coordinates (another shape raises ``ValueError``). With coordinates each mode is
        a 3-D view of the sensors displaced by the real part of the shape along their
        directions (``+Z`` when none is known), nearest neighbours joined by lines; without,
        the real part and the magnitude of the shape are bars by channel (so too for a single
        channel, whose 3-D view would be one stem).
    max_columns : int
        Panels per row.
    fig : Figure or SubFigure, optional
        Where to draw; default a new figure.

    Returns
    -------
    Figure or SubFigure
        One axes per physical mode (a single axes with a note when there is none).
    """
    report = Report.coerce(report)
    modes = report.physical_modes
    inp = report.input
    directions = inp.output_directions
    if xyz is None and inp.mode_shape_xyz is not None:
        xyz = as_floats(inp.mode_shape_xyz)
        directions = inp.mode_shape_directions
    elif xyz is None and inp.output_xyz is not None and not inp.reciprocity:
        n_xyz = len(inp.output_xyz)
        rows = (report.shape_output_indices() if n_xyz == len(inp.output_names)
                else list(range(n_xyz)))  # outputs the run kept
        xyz = as_floats(inp.output_xyz)[rows]
        directions = None if directions is None else [directions[i] for i in rows
                                                      if i < len(directions)]
    geometry = xyz is not None
    if geometry and modes:
        xyz = np.asarray(xyz, dtype=float)
        n_out = _shape(modes[0]).size
        if xyz.shape != (n_out, 3):
            raise ValueError(f"xyz has shape {xyz.shape}, the shapes need ({n_out}, 3)")
        geometry = n_out > 1  # one sensor in 3-D says nothing: its bar does
    n_cols = max(1, min(len(modes), max_columns))
    n_rows = max(1, math.ceil(len(modes) / n_cols))
    fig = _canvas(fig, (3.2 * n_cols, 2.8 * n_rows + 0.6))
    if not modes:
        ax = fig.add_subplot()
        ax.set_axis_off()
        ax.text(0.5, 0.5, "no physical mode", ha="center", va="center", transform=ax.transAxes)
    for k, mode in enumerate(modes):
        shape = _shape(mode)
        spread = np.nan_to_num(as_floats(mode.mode_shape_std), nan=0.0)
        if spread.size != shape.size:
            spread = np.zeros(shape.size)
        if geometry:
            ax = fig.add_subplot(n_rows, n_cols, k + 1, projection="3d")
            _draw_geometry(ax, xyz, shape.real, _direction_vectors(directions, shape.size),
                           spread)
        else:
            ax = fig.add_subplot(n_rows, n_cols, k + 1)
            _draw_shape_bars(ax, shape, _shape_channel_names(report, shape.size), k == 0,
                             spread)
        zeta = mode.damping_ratio
        damping = f", ζ {100 * zeta:.2f} %" if zeta is not None else ""
        ax.set_title(f"mode {mode.mode_number or '-'}: {_hz(mode.frequency_hz)}{damping}",
                     fontsize=8)
    how = ("real part on the sensor geometry; thin bars: ± the bootstrap spread" if geometry
           else "real part and magnitude by channel; error bars: ± the bootstrap spread")
    fig.suptitle(f"Shapes of the physical modes ({how})", fontsize=10)
    return fig


def overview(
    report: ReportLike,
    poles: PoleTable | Mapping[str, np.ndarray] | None = None,
    frf: Mapping[str, np.ndarray] | Sequence[np.ndarray] | None = None,
    xyz: np.ndarray | None = None,
    stabilization: StabilizationPoles | Mapping[str, np.ndarray] | None = None,
) -> Figure:
    """The panels in one figure, each where its data exist.

    Parameters
    ----------
    report : Report or dict
        The report.
    poles : PoleTable or dict, optional
        Every bootstrap pole; without them (or with none) there is no pole map.
    frf : dict or sequence, optional
        ``{"frequency", "measured", "synthesized"}`` or ``(f, measured, synthesized)``;
        without it there is no FRF panel (and no FRF behind the pole map).
    xyz : ndarray, optional
        Sensor coordinates for the mode shapes (default the report's).
    stabilization : StabilizationPoles or dict, optional
        The order scan's poles; without them there is no stabilization diagram.

    Returns
    -------
    Figure
        From top to bottom: stabilization diagram, pole map, FRF fit beside the
        physicalness bars, mode shapes.
    """
    from matplotlib.figure import Figure

    report = Report.coerce(report)
    has_poles = poles is not None and _pole_columns(poles)["frequency_hz"].size > 0
    has_stab = _has_stabilization(stabilization)
    parts = _frf_parts(frf)
    n_shapes = max(1, len(report.physical_modes))
    columns = min(n_shapes, OVERVIEW_SHAPE_COLUMNS)
    heights = (([4.8] if has_stab else []) + ([4.6] if has_poles else []) + [4.6]
               + [2.5 * math.ceil(n_shapes / columns) + 0.6])
    fig = Figure(figsize=(15.0, sum(heights)), layout="constrained")
    subs = list(np.ravel(fig.subfigures(len(heights), 1, height_ratios=heights)))
    if has_stab:
        stabilization_diagram(report, stabilization, parts, fig=subs.pop(0))
    if has_poles:
        pole_map(report, poles, parts, fig=subs.pop(0))
    middle = subs.pop(0)
    if parts is not None:
        left, right = middle.subfigures(1, 2, width_ratios=[3, 2])
        frf_fit(report, parts[0], parts[1], parts[2], fig=left)
        physicalness_bars(report, fig=right)
    else:
        physicalness_bars(report, fig=middle)
    mode_shapes(report, xyz, max_columns=columns, fig=subs.pop(0))
    return fig


def trend(history: History, *, fig: Figure | SubFigure | None = None) -> Figure | SubFigure:
    """Frequency and damping of the tracked modes over time, with bootstrap bands.

    Parameters
    ----------
    history : History
        What :func:`automodal.app.monitoring.build_history` made (or
        :func:`automodal.io.history.read_history` read).
    fig : Figure or SubFigure, optional
        Where to draw; default a new figure.

    Returns
    -------
    Figure or SubFigure
        Two axes sharing the time axis (UTC): above, each mode's frequency change from the
        baseline in % with its bootstrap 95 % band and the alarm floor
        ``±min_relative_shift`` dashed; below, the damping ratio in % with its band. Flagged
        points are ringed in red (``gid="flagged"``), missing modes drawn as red crosses at
        0 % (``gid="missing"``). When a report has no test date (its time is when the
        report was made, and a batch makes them all within minutes) the x axis is the
        reports' order instead of time, with a note saying so.
    """
    fig = _canvas(fig, (10.0, 6.5))
    ax_f, ax_d = fig.subplots(2, 1, sharex=True)
    x, x_label = _trend_axis(history, ax_d)
    flagged_label, missing_label = "flagged", "missing"
    colors = mode_colors(history.n_modes)
    for m in range(history.n_modes):
        color = colors[m]
        fb = float(history.baseline_frequency_hz[m])
        rel = 100.0 * (history.frequency_hz[:, m] - fb) / fb
        band = 100.0 * (history.frequency_ci95_hz[:, m, :] - fb) / fb
        zeta = 100.0 * history.damping_ratio[:, m]
        zband = 100.0 * history.damping_ci95[:, m, :]
        label = f"mode {int(history.mode_numbers[m])} ({_hz(fb)})"
        for ax, y, b in ((ax_f, rel, band), (ax_d, zeta, zband)):
            ax.plot(x, y, "o-", color=color, ms=3, lw=1.0, label=label if ax is ax_f else None)
            ax.fill_between(x, b[:, 0], b[:, 1], color=color, alpha=0.2, lw=0)
            hit = history.mode_flagged[:, m] & np.isfinite(y)
            if hit.any():
                ax.scatter(x[hit], y[hit], s=70, facecolors="none", edgecolors="tab:red",
                           linewidths=1.5, zorder=5, gid="flagged", label=flagged_label)
                flagged_label = None
        gone = history.missing[:, m]
        if gone.any():
            ax_f.scatter(x[gone], np.zeros(int(gone.sum())), marker="x", s=60, color="tab:red",
                         zorder=5, gid="missing", label=missing_label)
            missing_label = None
    floor = 100.0 * history.thresholds.min_relative_shift
    for level in (-floor, floor):
        ax_f.axhline(level, color="0.5", ls="--", lw=0.8, zorder=0)
    ax_f.axhline(0.0, color="0.75", lw=0.6, zorder=0)
    ax_f.set_ylabel("frequency change (%)")
    ax_d.set_ylabel("damping ratio (%)")
    ax_d.set_xlabel(f"{x_label}; bands: bootstrap 95 % intervals; dashed: alarm floor")
    if not history.n_modes:
        ax_f.text(0.5, 0.5, "the baseline has no physical mode", ha="center", va="center",
                  transform=ax_f.transAxes)
    ax_d.tick_params(axis="x", labelrotation=25)
    handles, labels = ax_f.get_legend_handles_labels()
    order = sorted(range(len(labels)), key=lambda k: labels[k] in ("flagged", "missing"))
    if handles:
        _top_legend(ax_f, fig, [handles[k] for k in order], [labels[k] for k in order],
                    max_columns=5)
    n_flagged = int(np.sum(history.flagged))
    fig.suptitle(f"Modes over time against {Path(history.baseline_label).name}: "
                 f"{n_flagged} of {history.n_times} tests flagged", fontsize=10)
    return fig


def _trend_axis(history: History, ax: Axes) -> tuple[np.ndarray, str]:
    """The x values of :func:`trend` and their label: the test dates (UTC) when every
    report has one, else the reports' order 1, 2, ... (ticks named by the reports when
    few), since times of making reports do not space tests apart."""
    import datetime as dt

    undated = sum(s != "test_date" for s in history.time_sources)
    if not undated:
        times = [dt.datetime.fromisoformat(t.replace("Z", "+00:00")).replace(tzinfo=None)
                 for t in history.times]
        return np.array(times, dtype="datetime64[s]"), "test date (UTC)"
    x = np.arange(1, history.n_times + 1)
    if history.n_times <= 30:
        ax.set_xticks(x, [Path(label).stem for label in history.labels])
    ax.text(0.0, -0.38, f"{undated} of {history.n_times} reports have no test date (input "
            "attribute test_date): reports in order, at equal spacing", fontsize=8,
            color="tab:red", transform=ax.transAxes, gid="no-test-date")
    return x, "report, in order of test date or else of making"


# ------------------------------------------------------------------------------ saving


def save_figure(fig: Figure, path: str | os.PathLike[str], dpi: int = 150) -> Path:
    """Write a figure atomically; the suffix of ``path`` chooses the format.

    Parameters
    ----------
    fig : Figure
    path : str or path-like
        ``*.png``, ``*.svg``, ``*.pdf`` (or any other format matplotlib writes).
    dpi : int
        Resolution of raster formats.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    from automodal.io.atomic import atomic_path

    target = Path(path)
    with atomic_path(target) as tmp:
        fig.savefig(tmp, dpi=dpi, format=target.suffix.lstrip(".").lower() or None)
    return target


def save_figures(
    report: ReportLike,
    arrays: Mapping[str, Any] | None,
    folder: str | os.PathLike[str],
    dpi: int = 150,
) -> list[Path]:
    """Write the standard set of figures of a report as PNG files into ``folder``.

    Parameters
    ----------
    report : Report or dict
        The report.
    arrays : dict, optional
        ``{"poles": PoleTable or dict, "frf": dict or (f, measured, synthesized),
        "stabilization": StabilizationPoles or dict}``, as
        :func:`automodal.io.report.read_report_arrays` gives (any may be missing or
        empty); default the report's own ``arrays``.
    folder : str or path-like
        Created when missing.
    dpi : int
        Resolution.

    Returns
    -------
    list of pathlib.Path
        The files written, in the order of :data:`FIGURE_NAMES`: ``overview.png``,
        ``stabilization.png`` (with the order scan's poles), ``poles.png`` (with poles),
        ``frf_fit.png`` (with FRFs), ``physicalness.png``, ``mode_shapes.png`` and
        ``automac.png``.
    """
    report = Report.coerce(report)
    if arrays is None:
        arrays = {"poles": report.arrays.poles, "frf": report.arrays.frf,
                  "stabilization": report.arrays.stabilization}
    poles = arrays.get("poles")
    if poles is not None and _pole_columns(poles)["frequency_hz"].size == 0:
        poles = None
    stab = arrays.get("stabilization")
    stab = stab if _has_stabilization(stab) else None
    parts = _frf_parts(arrays.get("frf"))
    makers = {
        "overview": lambda: overview(report, poles, parts, stabilization=stab),
        "stabilization": (None if stab is None
                          else lambda: stabilization_diagram(report, stab, parts)),
        "poles": None if poles is None else lambda: pole_map(report, poles, parts),
        "frf_fit": None if parts is None else lambda: frf_fit(report, *parts),
        "physicalness": lambda: physicalness_bars(report),
        "mode_shapes": lambda: mode_shapes(report),
        "automac": lambda: automac(report),
    }
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    return [
        save_figure(make(), out / f"{name}.png", dpi)
        for name, make in makers.items()
        if make is not None
    ]


# ------------------------------------------------------------------------------ drawing


def _canvas(fig: Figure | SubFigure | None, size: tuple[float, float]) -> Figure | SubFigure:
    """``fig``, or a new constrained-layout figure of ``size`` inches."""
    if fig is not None:
        return fig
    from matplotlib.figure import Figure

    return Figure(figsize=size, layout="constrained")


def _top_legend(ax: Axes, fig: Figure | SubFigure, handles: list[Any],
                labels: list[str] | None = None, max_columns: int = 6,
                fontsize: float = 8.0) -> None:
    """A frameless legend above ``ax`` in as many columns as fit the figure's width (long
    channel names wrap onto more rows instead of running off the figure)."""
    if labels is None:
        labels = [h.get_label() for h in handles]
    if not handles:
        return
    width_pt = fig.bbox.width / fig.dpi * 72.0 * 0.92
    entry_pt = (max(len(t) for t in labels) + 5.0) * 0.58 * fontsize  # text and marker
    ncol = int(max(1, min(len(handles), max_columns, width_pt // max(entry_pt, 1.0))))
    ax.legend(handles, labels, loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=ncol,
              frameon=False, fontsize=fontsize, borderaxespad=0.2)


def _draw_frf_sum(ax: Axes, frequency: np.ndarray, H: np.ndarray,
                  operational: bool = False) -> Any:
    """The FRF magnitude summed over channels on a log twin axis behind ``ax``'s artists
    (``operational``: output-only half spectra, named so)."""
    twin = ax.twinx()
    total = np.sum(np.abs(np.asarray(H)), axis=(1, 2))
    name = "Σ|G| half spectra" if operational else "Σ|H| over channels"
    (line,) = twin.plot(frequency, total, color="0.25", lw=0.8, alpha=0.7, gid="frf-sum",
                        label=name)
    twin.set_yscale("log")
    positive = total[np.isfinite(total) & (total > 0)]
    if positive.size and positive.max() > positive.min():
        lo, hi = np.log10(positive.min()), np.log10(positive.max())
        margin = 0.03 * (hi - lo)
        twin.set_ylim(10 ** (lo - margin), 10 ** (lo + POLE_MAP_HEADROOM * (hi - lo + margin)))
    twin.set_ylabel(name)
    ax.set_zorder(twin.get_zorder() + 1)
    ax.patch.set_visible(False)
    return line


def _pole_legend_handles() -> list[Any]:
    """Legend entries of the pole map."""
    from matplotlib.lines import Line2D

    def dot(color: str, size: float, marker: str, label: str) -> Line2D:
        return Line2D([], [], ls="", marker=marker, ms=size, color=color, label=label)

    return [
        dot(PHYSICAL_COLOR, 5, "o", "physical cluster"),
        dot(NON_PHYSICAL_COLOR, 4, "x", "other cluster"),
        dot(TRASHBOX_COLOR, 4, ".", "Trashbox"),
    ]


def _label_modes(ax: Axes, fig: Figure | SubFigure, modes: list[ReportMode],
                 colors: list[Any]) -> None:
    """Each mode's frequency as a vertical label at the top of ``ax``, with a dotted line
    at the mode; labels of close modes are moved apart (at least one label width) and
    joined to their mode by a thin leader."""
    if not modes:
        return
    lo, hi = ax.get_xlim()
    f = np.array([m.frequency_hz for m in modes], dtype=float)
    order = np.argsort(f)
    width_pt = fig.bbox.width / fig.dpi * 72.0 * 0.85  # the axes' share of the figure
    gap = 1.5 * LABEL_FONT / max(width_pt, 1.0)
    at = spread_positions((f[order] - lo) / (hi - lo), gap)
    for k, x in zip(order, at):
        color = colors[k]
        ax.axvline(f[k], color=color, lw=0.6, ls=":", zorder=0)
        ax.annotate(
            _mode_tag(modes[k]), xy=(f[k], 0.78), xycoords=ax.get_xaxis_transform(),
            xytext=(x, 0.985), textcoords="axes fraction", color=color, rotation=90,
            ha="center", va="top", fontsize=LABEL_FONT, gid="mode-label",
            bbox={"boxstyle": "square,pad=0.1", "fc": "white", "ec": "none", "alpha": 0.8},
            arrowprops={"arrowstyle": "-", "color": color, "lw": 0.5, "shrinkA": 0,
                        "shrinkB": 0},
        )


def _style_handles(with_synth: bool) -> list[Any]:
    """Legend entries for the line styles of :func:`frf_fit`."""
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color="0.2", lw=0.9, label="measured")]
    if with_synth:
        handles.append(Line2D([], [], color="0.2", lw=1.3, ls="--", label="synthesized"))
    return handles


def _draw_shape_bars(ax: Axes, shape: np.ndarray, names: list[str], legend: bool,
                     spread: np.ndarray | None = None) -> None:
    """Real part and magnitude of a shape as bars by channel, the spread as error bars on
    the magnitude."""
    x = np.arange(shape.size)
    ax.bar(x - 0.2, shape.real, width=0.4, color=PHYSICAL_COLOR, label="real part", gid="real")
    ax.bar(x + 0.2, np.abs(shape), width=0.4, color="none", edgecolor="0.3", lw=0.8,
           label="magnitude", gid="magnitude")
    if spread is not None and np.any(spread > 0):
        ax.errorbar(x + 0.2, np.abs(shape), yerr=spread, fmt="none", ecolor="tab:red",
                    elinewidth=0.9, capsize=1.5, gid="shape-spread", label="± spread")
    ax.axhline(0.0, color="0.3", lw=0.6)
    ax.set_ylim(-1.15, 1.15)
    ax.set_xticks(x)
    ax.set_xticklabels(names, rotation=90 if shape.size > 6 else 0, fontsize=7)
    ax.tick_params(axis="y", labelsize=7)
    if legend:
        ax.legend(fontsize=6, loc="lower right", frameon=False)


def _draw_geometry(ax: Any, xyz: np.ndarray, real: np.ndarray, directions: np.ndarray,
                   spread: np.ndarray | None = None) -> None:
    """Sensors displaced by the real part of a shape, in a 3-D axes with its coordinates.

    Grey: the sensors at rest and the lines between nearest neighbours; stems from rest to
    the displaced sensor, coloured by the sign and size of the displacement (red out,
    blue in); thin dark lines join the displaced sensors; thin red bars along each
    sensor's direction show ± the shape's spread. The scale (coordinate units per unit of
    shape: the largest entry is drawn as 30 % of the structure's span) is written in the
    corner.
    """
    from matplotlib import colormaps

    span = float(np.max(np.ptp(xyz, axis=0))) if xyz.size else 0.0
    scale = 0.3 * (span if span > 0 else 1.0) / max(float(np.max(np.abs(real))), 1e-12)
    moved = xyz + scale * real[:, None] * directions
    cmap = colormaps["coolwarm"]
    for a, b in _neighbour_edges(xyz):
        ax.plot(*xyz[[a, b]].T, color="0.65", lw=0.8, gid="undeformed")
        ax.plot(*moved[[a, b]].T, color="0.2", lw=0.8, alpha=0.7, gid="deformed")
    for p, q, r in zip(xyz, moved, real):
        ax.plot(*np.stack([p, q]).T, color=cmap(0.5 + 0.5 * float(np.clip(r, -1, 1))), lw=1.4)
    if spread is not None and np.any(spread > 0):
        for q, d, e in zip(moved, directions, spread):
            ends = np.stack([q - scale * e * d, q + scale * e * d])
            ax.plot(*ends.T, color="tab:red", lw=2.2, alpha=0.5, gid="shape-spread")
    ax.scatter(*xyz.T, s=5, color="0.55", depthshade=False)
    ax.scatter(*moved.T, s=22, c=real, cmap=cmap, vmin=-1, vmax=1, edgecolors="0.2",
               linewidths=0.4, depthshade=False, gid="sensors")
    lo = np.minimum(xyz.min(axis=0), moved.min(axis=0))
    hi = np.maximum(xyz.max(axis=0), moved.max(axis=0))
    pad = 0.05 * max(float(np.max(hi - lo)), 1e-12)
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_zlim(lo[2] - pad, hi[2] + pad)
    ax.set_box_aspect(np.maximum(hi - lo + 2 * pad, 0.3 * float(np.max(hi - lo + 2 * pad))),
                      zoom=0.85)  # the axis labels stay within the panel
    ax.set_proj_type("ortho")
    ax.view_init(elev=25, azim=-60)
    for axis, name in ((ax.xaxis, "x"), (ax.yaxis, "y"), (ax.zaxis, "z")):
        axis.set_pane_color((1.0, 1.0, 1.0, 0.0))
        axis.set_label_text(name, fontsize=7)
    from matplotlib.ticker import MaxNLocator

    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(4))
    ax.tick_params(labelsize=6, pad=0)
    ax.text2D(0.0, 1.0, f"shape × {scale:.3g}", transform=ax.transAxes, fontsize=6,
              color="0.3", va="top", gid="shape-scale")  # clear of the x axis' label


def _neighbour_edges(xyz: np.ndarray, max_points: int = 500) -> list[tuple[int, int]]:
    """Pairs of sensors at the smallest distance between any two (a lattice's edges)."""
    n = xyz.shape[0]
    if n < 2 or n > max_points:
        return []
    d = np.linalg.norm(xyz[:, None, :] - xyz[None, :, :], axis=2)
    upper = d[np.triu_indices(n, 1)]
    positive = upper[upper > 0]
    if positive.size == 0:
        return []
    a, b = np.nonzero(np.triu((d > 0) & (d <= 1.01 * positive.min()), 1))
    return list(zip(a.tolist(), b.tolist()))


# ------------------------------------------------------------------------------ data


def _pole_columns(poles: PoleTable | Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Frequency, cluster and replicate of every pole, from a PoleTable or a dict."""
    return _columns(poles, {"frequency_hz": float, "cluster": int, "replicate": int})


def _columns(table: Any, names: Mapping[str, type]) -> dict[str, np.ndarray]:
    """Columns of equal length from a dataclass of arrays or a dict (missing: empty)."""

    def column(name: str, dtype: type) -> np.ndarray:
        value = table.get(name) if isinstance(table, Mapping) else getattr(table, name, None)
        return np.zeros(0, dtype) if value is None else np.asarray(value, dtype=dtype).ravel()

    cols = {name: column(name, dtype) for name, dtype in names.items()}
    n = next(iter(cols.values())).size
    if any(c.size != n for c in cols.values()):
        raise ValueError(f"{', '.join(names)} differ in length")
    return cols


def _has_stabilization(stab: Any) -> bool:
    """Whether ``stab`` holds any pole of the order scan."""
    if stab is None:
        return False
    return _columns(stab, {"order": int})["order"].size > 0


def _frf_parts(
    frf: Mapping[str, np.ndarray] | Sequence[np.ndarray] | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None] | None:
    """``(frequency, measured, synthesized or None)`` from a dict or a sequence, or None."""
    if frf is None:
        return None
    if isinstance(frf, Mapping):
        freq, measured, synth = (frf.get(k) for k in ("frequency", "measured", "synthesized"))
    else:
        items = list(frf) + [None] * (3 - len(frf))
        freq, measured, synth = items[:3]
    if freq is None or measured is None or np.asarray(freq).size == 0:
        return None
    return np.asarray(freq, dtype=float), np.asarray(measured), synth


@dataclass
class _Cluster:
    """Whether any mode of a cluster is physical, and its lowest finite frequency."""

    physical: bool = False
    frequency_hz: float = math.inf


_NO_CLUSTER = _Cluster()


def _clusters(report: Report) -> dict[int, _Cluster]:
    """Cluster id -> whether any of its modes is physical, and the lowest frequency."""
    out: dict[int, _Cluster] = {}
    for mode in report.modes:
        if mode.cluster is None:
            continue
        entry = out.setdefault(mode.cluster, _Cluster())
        entry.physical |= mode.physical
        if mode.has_frequency:
            entry.frequency_hz = min(entry.frequency_hz, float(mode.frequency_hz))
    return out


def _cluster_colors(by_cluster: Mapping[int, _Cluster], present: np.ndarray) -> dict[int, Any]:
    """A colour per cluster in frequency order: distinct strong colours for the physical
    clusters (:func:`mode_colors`), light tab20 colours for the others."""
    from matplotlib import colormaps

    muted = colormaps["tab20"].colors[1::2]
    order = sorted((int(c) for c in present),
                   key=lambda c: by_cluster.get(c, _NO_CLUSTER).frequency_hz)
    physical = [c for c in order if by_cluster.get(c, _NO_CLUSTER).physical]
    colors: dict[int, Any] = dict(zip(physical, mode_colors(len(physical))))
    others = [c for c in order if c not in colors]
    colors.update({c: muted[k % len(muted)] for k, c in enumerate(others)})
    return colors


def mode_colors(n: int) -> list[Any]:
    """``n`` distinct colours: tab10 without its grey (the colour of what is not physical)
    up to 9, else ``n`` hues evenly spaced around the colour wheel, saturated and dark
    enough (value 0.75) that a label in the colour reads on white (the yellows and light
    greens of the turbo map did not), so that no two modes share a colour."""
    from matplotlib import colormaps
    from matplotlib.colors import hsv_to_rgb

    strong = [c for k, c in enumerate(colormaps["tab10"].colors) if k != 7]
    if n <= len(strong):
        return strong[:n]
    hues = np.linspace(0.0, 0.85, n)
    return [tuple(hsv_to_rgb((h, 0.9, 0.75))) + (1.0,) for h in hues]


def spread_positions(x: np.ndarray, gap: float, lo: float = 0.0, hi: float = 1.0) -> np.ndarray:
    """Positions as near to the sorted ``x`` as possible, at least ``gap`` apart, in
    ``[lo, hi]`` (labels that must not overlap).

    Groups of labels that would overlap are spread evenly around their mean; the groups
    merge until no two are closer than ``gap``.
    """
    x = np.asarray(x, dtype=float)
    if x.size == 0:
        return x
    gap = min(gap, (hi - lo) / max(x.size, 1))
    groups: list[list[float]] = []  # [start position, count, sum of targets]
    for xi in np.sort(x):
        groups.append([xi, 1, xi])
        while len(groups) > 1 and groups[-2][0] + groups[-2][1] * gap > groups[-1][0]:
            b = groups.pop()
            a = groups[-1]
            a[1] += b[1]
            a[2] += b[2]
            a[0] = a[2] / a[1] - (a[1] - 1) * gap / 2.0
        g = groups[-1]
        g[0] = min(max(g[0], lo), hi - (g[1] - 1) * gap)
    return np.concatenate([g[0] + gap * np.arange(g[1]) for g in groups])


def _shape(mode: ReportMode) -> np.ndarray:
    """A mode's shape as a complex array (``null`` entries as 0)."""
    return np.nan_to_num(mode.shape, nan=0.0)


def _direction_vectors(directions: Sequence[str] | None, n: int) -> np.ndarray:
    """Unit vectors of directions such as ``"+X"`` or ``"-Z"``; unknown ones ``+Z``."""
    out = np.tile(np.array(_DIRECTIONS["Z"]), (n, 1))
    for i, d in enumerate(list(directions or [])[:n]):
        text = str(d).strip().upper()
        axis = _DIRECTIONS.get(text.lstrip("+-"))
        if axis is not None:
            out[i] = (-1.0 if text.startswith("-") else 1.0) * np.array(axis)
    return out


def _channel_names(report: Report, ny: int, nu: int) -> tuple[list[str], list[str]]:
    """Output and input names from the report, ``y1..``/``u1..`` where they are missing."""

    def names(given: list[str], n: int, prefix: str) -> list[str]:
        return given[:n] if len(given) >= n else [f"{prefix}{i + 1}" for i in range(n)]

    return (names(report.input.output_names, ny, "y"),
            names(report.input.input_names, nu, "u"))


def _shape_channel_names(report: Report, n: int) -> list[str]:
    """Names of the mode-shape entries (:attr:`Report.shape_channels`), ``y1..`` when the
    report names fewer than ``n``."""
    given = report.shape_channels
    return given[:n] if len(given) >= n else _channel_names(report, n, 0)[0]


def _strongest_channels(H: np.ndarray, n: int) -> list[tuple[int, int]]:
    """The ``n`` output/input pairs of largest RMS magnitude, in channel order."""
    rms = np.sqrt(np.mean(np.abs(H) ** 2, axis=0)) if H.shape[0] else np.zeros(H.shape[1:])
    rows, cols = np.unravel_index(np.argsort(rms, axis=None)[::-1][: max(1, n)], rms.shape)
    return sorted(zip(rows.tolist(), cols.tolist()))


def _wrapped_phase(f: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Phase in degrees in (-180, 180], the line broken (NaN) where it wraps."""
    deg = np.degrees(np.angle(h))
    jumps = np.flatnonzero(np.abs(np.diff(deg)) > 180.0) + 1
    return np.insert(f, jumps, np.nan), np.insert(deg, jumps, np.nan)


def _ci_halfwidths(modes: list[ReportMode], f: np.ndarray) -> np.ndarray:
    """``(2, n)`` distances from each frequency to the ends of its 95 % interval."""
    out = np.zeros((2, len(modes)))
    for k, mode in enumerate(modes):
        lo, hi = mode.frequency_ci95_hz
        if lo is not None and hi is not None:
            out[:, k] = max(0.0, f[k] - lo), max(0.0, hi - f[k])
    return out


def _band(report: Report, freq: np.ndarray) -> tuple[float, float]:
    """The analysed band from the report, else the span of ``freq``, else (0, 1)."""
    band = report.band_hz
    if band is not None:
        return band
    finite = freq[np.isfinite(freq)] if freq.size else freq
    if finite.size and finite.max() > finite.min():
        return float(finite.min()), float(finite.max())
    return 0.0, 1.0


def _pct_value(x: float) -> str:
    """A fraction as a percentage with two significant digits, e.g. ``1.2 %``."""
    return f"{100 * x:.2g} %"


def _operational(report: Report) -> bool:
    """Whether the report's data were output-only half spectra."""
    return report.input.attributes.get("analysis") == "operational"


def magnitude_label(quantity: str, operational: bool = False) -> str:
    """The magnitude axis label of FRFs of ``quantity`` (``displacement``, ``velocity`` or
    ``acceleration``): its FRF's name and SI units, e.g. ``|H| accelerance ((m/s²)/N)``;
    ``operational``: half spectra of output-only data."""
    if operational:
        unit = _QUANTITY_UNIT.get(quantity)
        return f"|G| half spectrum ({unit})²" if unit else "|G| half spectrum"
    kind, unit = _QUANTITY_FRF.get(quantity, ("FRF", ""))
    return f"|H| {kind} ({unit})" if unit else f"|H| {kind}"


def _fit_error(report: Report, H: np.ndarray, S: np.ndarray | None) -> np.ndarray | None:
    """The normalised error of the synthesis per channel: the report's (over every line),
    else computed from the arrays drawn, else ``None``."""
    from automodal.core.synthesis import normalised_error

    stored = report.summary.frf_fit_error
    if stored is not None:
        e = as_floats([x for row in stored for x in row])
        if e.size == H.shape[1] * H.shape[2]:
            return e.reshape(H.shape[1], H.shape[2])
    return None if S is None else normalised_error(H, S)


def _pct(x: float) -> str:
    """A fraction as a percentage, e.g. ``1 %``."""
    return f"{100 * x:g} %"


def _mode_tag(mode: ReportMode) -> str:
    """A physical mode's label in every figure: its number and frequency, ``3: 596.4 Hz``
    (the frequency alone for a mode without a number)."""
    number = mode.mode_number
    return _hz(mode.frequency_hz) if number is None else f"{number}: {_hz(mode.frequency_hz)}"


def _hz(f: float) -> str:
    """A frequency with four significant digits, e.g. ``9.597 Hz``."""
    return f"{f:.4g} Hz"
