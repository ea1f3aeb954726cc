"""One :class:`~automodal.result.Result` from the results of a band's sub-bands.

The pipeline identifies a band with many resonances sub-band by sub-band
(:mod:`automodal.core.sub_bands`); each sub-band's run also sees one resonance beyond each
of its cuts. The merged result keeps from each run what lies in its core: the modes (with
their clusters renumbered so that they stay distinct) and their clusters' bootstrap poles,
the Trashbox's poles, the stabilization diagram's poles and the FRF synthesis. The orders
of every sub-band are kept in ``orders["sub_bands"]``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from automodal.core.stabilization import StabilizationPoles
from automodal.core.sub_bands import SubBand
from automodal.core.summary import numbered
from automodal.core.synthesis import normalised_error
from automodal.result import NoiseInfo, PoleTable, Result

__all__ = ["merge_sub_bands"]


def merge_sub_bands(
    results: Sequence[Result],
    plan: Sequence[SubBand],
    settings: dict,
    warnings: list[str],
    runtime_s: float,
) -> Result:
    """The sub-bands' results as one.

    Parameters
    ----------
    results : sequence of Result
        One run per sub-band, in the order of ``plan``.
    plan : sequence of SubBand
        The sub-bands (their cores do not overlap and cover the band).
    settings : dict
        The run's settings (:meth:`automodal.settings.Settings.to_dict`).
    warnings : list of str
        Warnings of the whole run, before those of the sub-bands (which follow, each once).
    runtime_s : float
        Wall time of the whole run.
    """
    modes, poles, stab, fit = [], [], [], []
    offset = 0
    for k, (band, r) in enumerate(zip(plan, results)):
        last = k == len(plan) - 1
        kept = [m for m in r.modes if band.holds(m.frequency_hz, last)]
        p = r.poles
        # the kept clusters' poles, and the Trashbox's in the core (the other clusters'
        # poles are a neighbour's, which keeps them)
        inside = np.isin(p.cluster, [m.cluster for m in kept]) | (
            (p.cluster < 0) & band.holds(p.frequency_hz, last))
        for m in kept:
            m.cluster += offset
            modes.append(m)
        poles.append(PoleTable(p.frequency_hz[inside], p.damping_ratio[inside],
                               np.where(p.cluster >= 0, p.cluster + offset, -1)[inside],
                               p.replicate[inside]))
        if r.stabilization is not None:
            s = r.stabilization
            keep = band.holds(s.frequency_hz, last)
            stab.append(StabilizationPoles(s.order[keep], s.frequency_hz[keep],
                                           s.damping_ratio[keep], s.stability[keep]))
        if r.frf_fit is not None:
            f, measured, synthesized = r.frf_fit
            keep = band.holds(f, last)
            fit.append((f[keep], measured[keep], synthesized[keep]))
        # past every cluster id of this result (a sub-band split again has merged ids
        # beyond its count of clusters)
        offset += max([r.n_clusters, *(m.cluster + 1 for m in r.modes),
                       int(np.max(p.cluster, initial=-1)) + 1])
    table = PoleTable(*(np.concatenate([getattr(t, a) for t in poles])
                        for a in ("frequency_hz", "damping_ratio", "cluster", "replicate")))
    frf_fit = _stacked_fit(fit)
    first = results[0]
    return Result(
        modes=numbered(modes),
        trashbox_members=int(np.count_nonzero(table.cluster < 0)),
        n_clusters=len({m.cluster for m in modes}),
        settings=settings,
        warnings=_once([*warnings, *(w for r in results for w in r.warnings)]),
        poles=table,
        band_hz=(float(plan[0].core_hz[0]), float(plan[-1].core_hz[1])),
        orders=_orders(results, plan),
        runtime_s=runtime_s,
        reference_model=None,
        reciprocity=first.reciprocity,
        shape_channels=list(first.shape_channels),
        n_lines=int(frf_fit[0].size) if frf_fit else first.n_lines,
        frf_fit=frf_fit,
        frf_fit_error=None if frf_fit is None else normalised_error(frf_fit[1], frf_fit[2]),
        stabilization=None if not stab else StabilizationPoles(
            *(np.concatenate([getattr(s, a) for s in stab])
              for a in ("order", "frequency_hz", "damping_ratio", "stability"))),
        noise=_noise(results),
    )


def _orders(results: Sequence[Result], plan: Sequence[SubBand]) -> dict:
    """``orders``: each sub-band's own (with its core, analysed band and peaks), and the
    summary keys of a single run: ``n0`` the sum over sub-bands (the states of the whole
    band), ``reference`` the largest sub-band reference order, ``form`` the sub-bands' when
    they agree, else ``"mixed"``."""
    bands = [{"core_hz": list(b.core_hz), "analysed_hz": list(b.analysed_hz),
              "n_peaks": b.n_peaks, **r.orders} for b, r in zip(plan, results)]
    first = results[0].orders
    forms = {r.orders.get("form") for r in results}
    return {
        "n0": int(sum(r.orders["n0"] for r in results)),
        "n0_rule": "sub-bands",
        "reference": int(max(r.orders["reference"] for r in results)),
        "weighting": first.get("weighting"),
        "form": forms.pop() if len(forms) == 1 else "mixed",
        "window_decay_per_s": first.get("window_decay_per_s"),
        "discrete_sample_rate_hz": first.get("discrete_sample_rate_hz"),
        "sub_bands": bands,
    }


def _stacked_fit(fit: list) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The sub-bands' FRF syntheses, core by core."""
    if not fit:
        return None
    return tuple(np.concatenate([part[i] for part in fit]) for i in range(3))


def _noise(results: Sequence[Result]) -> NoiseInfo | None:
    """The sub-bands' noise models as one: each channel's level the median over the
    sub-bands, the dispersion the largest (the most conservative); the source and
    assumptions of the first."""
    infos = [r.noise for r in results if r.noise is not None]
    if not infos:
        return None
    first = infos[0]
    level = {k: float(np.median([i.output_level.get(k, np.nan) for i in infos]))
             for k in first.output_level}
    return NoiseInfo(source=first.source, output_level=level,
                     n_averages=first.n_averages, assumptions=list(first.assumptions),
                     dispersion=max(i.dispersion for i in infos))


def _once(items: list[str]) -> list[str]:
    """The items in order, each once."""
    return list(dict.fromkeys(items))
