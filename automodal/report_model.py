"""The identification report (``docs/report.md``, version 1) as typed dataclasses.

:class:`Report` is the one interface to a report: :meth:`Report.from_result` builds it from
a :class:`~automodal.result.Result` and its input (the only place where report content is
made), :meth:`Report.to_dict` gives the JSON content (the contract of ``docs/report.md``,
keys in the order they are written), and :meth:`Report.from_dict` checks a parsed report
(JSON, or the ``report_json`` of an HDF5 report, see :func:`automodal.io.report.read_report`)
and refuses a malformed one with an :class:`~automodal.errors.InputError` naming the field.
What readers of a report need more than once is written here once: the mode-shape channels
(:attr:`Report.shape_channels`), the physical modes (:attr:`Report.physical_modes`), the
test's time (:meth:`Report.test_time`), a mode's complex shape (:attr:`ReportMode.shape`),
the modes as arrays for matching (:meth:`Report.mode_table`).

The model holds plain JSON values (``int``, ``float``, ``None`` for a number that was not
finite, ``str``, lists and dicts) so that ``Report.from_dict(r.to_dict()) == r`` and
``to_dict`` is exactly what is written. Keys a later writer may add are kept in the
``extra`` dict of their section and written back after the known ones.

Design decision: dataclasses here, plus a JSON Schema of the same content shipped as a
plain file (``automodal/schemas/report-v1.schema.json``) that the tests check every report
against with ``jsonschema``, rather than pydantic models. ``jsonschema`` is a test-only
dependency (no runtime dependency, no import cost), and the schema is a plain file that
tools in other languages can use; pydantic would be a runtime dependency that costs import
time, while the imports of ``automodal identify`` must stay fast.
"""

from __future__ import annotations

import datetime as _dt
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from automodal.errors import InputError
from automodal.io.json_safe import json_safe, non_finite_warnings

if TYPE_CHECKING:
    from automodal.core.matching import ModeTable
    from automodal.core.stabilization import StabilizationPoles
    from automodal.frfdata import FRFData
    from automodal.result import IdentifiedMode, PoleTable, Result

__all__ = [
    "DATE_KEYS",
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "FRFArrays",
    "MonitoringBlock",
    "Report",
    "ReportArrays",
    "ReportHeader",
    "ReportInput",
    "ReportMode",
    "ReportSettings",
    "ReportSummary",
    "Trashbox",
    "as_floats",
    "check_header",
    "unit_max",
]

FORMAT_NAME = "automodal-report"
"""Value of the report's ``format`` key (and of the HDF5 root attribute)."""

FORMAT_VERSION = 1
"""The report version automodal writes, and the newest it reads."""

DATE_KEYS = ("test_date", "date", "datetime", "timestamp")
"""Keys of a report's ``input.attributes`` read as the test's date (ISO 8601), in order."""

FRFArrays = tuple[np.ndarray, np.ndarray, "np.ndarray | None"]
"""``(frequency, measured, synthesized)``: FRFs of the analysed band for the report's plots.
``frequency`` has shape ``(n,)`` in Hz, ``measured`` and ``synthesized`` (which may be
``None``) shape ``(n, n_outputs, n_inputs)``."""

_UTC_FORMAT = "%Y-%m-%dT%H:%M:%SZ"
"""The report's times: UTC ISO 8601 with seconds and ``Z``."""

Number = float | int | None
"""A JSON number of the report; ``None`` where the value was not finite."""


# ------------------------------------------------------------------------------ checking


def _refuse(where: str, problem: str) -> InputError:
    return InputError(f"malformed report: field {where} {problem}")


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _int(x: Any, where: str) -> int:
    if isinstance(x, bool) or not isinstance(x, int):
        raise _refuse(where, f"is not an integer ({x!r})")
    return x


def _positive(x: Any, where: str) -> int:
    if _int(x, where) < 1:
        raise _refuse(where, f"is not a positive integer ({x!r})")
    return x


def _count(x: Any, where: str) -> int:
    if _int(x, where) < 0:
        raise _refuse(where, f"is negative ({x!r})")
    return x


def _number(x: Any, where: str) -> Number:
    """A finite number or ``None`` (a value that was not finite)."""
    if x is None or _is_number(x):
        return x
    raise _refuse(where, f"is not a finite number or null ({x!r})")


def _str(x: Any, where: str) -> str:
    if not isinstance(x, str):
        raise _refuse(where, f"is not a string ({x!r})")
    return x


def _bool(x: Any, where: str) -> bool:
    if not isinstance(x, bool):
        raise _refuse(where, f"is not true or false ({x!r})")
    return x


def _dict(x: Any, where: str) -> dict[str, Any]:
    if not isinstance(x, dict):
        raise _refuse(where, "is not an object")
    return x


def _list(x: Any, where: str, length: int | None = None) -> list[Any]:
    if not isinstance(x, list):
        raise _refuse(where, "is not a list")
    if length is not None and len(x) != length:
        raise _refuse(where, f"has {len(x)} entries, not {length}")
    return x


def _numbers(x: Any, where: str, length: int | None = None) -> list[Number]:
    return [_number(v, f"{where}[{i}]") for i, v in enumerate(_list(x, where, length))]


def _strings(x: Any, where: str) -> list[str]:
    return [_str(v, f"{where}[{i}]") for i, v in enumerate(_list(x, where))]


def _optional(check: Callable[[Any, str], Any]) -> Callable[[Any, str], Any]:
    def checked(x: Any, where: str) -> Any:
        return None if x is None else check(x, where)

    return checked


class _Fields:
    """The keys of one JSON object, taken one by one with a check; the rest is ``extra``."""

    def __init__(self, obj: Any, where: str) -> None:
        self.obj = _dict(obj, where)
        self.where = where
        self.taken: set[str] = set()

    def _at(self, key: str) -> str:
        return f"{self.where}.{key}" if self.where else key

    def req(self, key: str, check: Callable[[Any, str], Any]) -> Any:
        """A key the report must have."""
        self.taken.add(key)
        if key not in self.obj:
            raise _refuse(self._at(key), "is missing")
        return check(self.obj[key], self._at(key))

    def opt(self, key: str, check: Callable[[Any, str], Any], default: Any = None) -> Any:
        """A key added after the spec's first text (``default`` when absent)."""
        self.taken.add(key)
        if key not in self.obj:
            return default
        return check(self.obj[key], self._at(key))

    def extra(self) -> dict[str, Any]:
        """The keys not taken, as they are."""
        return {k: v for k, v in self.obj.items() if k not in self.taken}


def _put(out: dict[str, Any], key: str, value: Any) -> None:
    """Set ``key`` unless ``value`` is ``None`` (an addition the report did not have)."""
    if value is not None:
        out[key] = value


def check_header(report: Any) -> int:
    """The version of a parsed report, after checking that it is an automodal report this
    version reads.

    Parameters
    ----------
    report : any
        Parsed JSON content.

    Returns
    -------
    int
        Its ``version``.

    Raises
    ------
    InputError
        If it is not a dict with ``format`` :data:`FORMAT_NAME`, or its ``version`` is not
        an integer or is newer than :data:`FORMAT_VERSION`.
    """
    if not isinstance(report, dict) or report.get("format") != FORMAT_NAME:
        raise InputError(f"not an automodal report (format is not {FORMAT_NAME!r})")
    version = report.get("version")
    if isinstance(version, bool) or not isinstance(version, int):
        raise InputError(f"report version {version!r} is not an integer")
    if version > FORMAT_VERSION:
        raise InputError(
            f"report version {version} is newer than this automodal reads ({FORMAT_VERSION})"
        )
    return version


# ------------------------------------------------------------------------------ sections


@dataclass
class ReportHeader:
    """``format``, ``version``, ``automodal_version`` and ``created`` (UTC ISO 8601)."""

    automodal_version: str
    created: str
    format: str = FORMAT_NAME
    version: int = FORMAT_VERSION

    @classmethod
    def from_dict(cls, report: Mapping[str, Any]) -> ReportHeader:
        """The header of a parsed report; refuses another format or a newer version
        (:func:`check_header`)."""
        version = check_header(report)
        fields = _Fields(report, "")
        return cls(
            automodal_version=fields.req("automodal_version", _str),
            created=fields.req("created", _str),
            format=FORMAT_NAME,
            version=version,
        )

    def to_dict(self) -> dict[str, Any]:
        return {"format": self.format, "version": self.version,
                "automodal_version": self.automodal_version, "created": self.created}


@dataclass
class ReportInput:
    """The ``input`` section: where the data came from and what it holds.

    Attributes
    ----------
    path, sha256 : str or None
        The input file and the SHA-256 of its bytes.
    n_freq, n_outputs, n_inputs : int
    band_hz : list of float
        The analysed band ``[lo, hi]``.
    quantity : str
    output_names, input_names : list of str
    attributes : dict
        The input's free attributes.
    frequency_range_hz : list of float or None
        Span of the whole input.
    output_xyz : list of [x, y, z] or None
        Sensor coordinates.
    output_directions : list of str or None
    mode_shape_nodes, mode_shape_directions : list or None
        Node number and direction (``"+X"``...) of each mode-shape channel, when known.
    mode_shape_xyz : list of [x, y, z] or None
        Coordinates of each mode-shape channel, when known (for the figures).
    n_lines_analysed : int or None
    reciprocity : bool or None
        Whether the shapes are on the inputs (reciprocity).
    mode_shape_channels : list of str or None
        The channels of the mode shapes (see :attr:`Report.shape_channels`).
    extra : dict
        Keys of a later writer.

    ``None`` for the additions after ``attributes`` means the report does not have them
    (``output_xyz`` and ``output_directions`` are then written as ``null``).
    """

    path: str | None
    sha256: str | None
    n_freq: int
    n_outputs: int
    n_inputs: int
    band_hz: list[Number]
    quantity: str
    output_names: list[str]
    input_names: list[str]
    attributes: dict[str, Any]
    frequency_range_hz: list[Number] | None = None
    output_xyz: list[list[Number]] | None = None
    output_directions: list[str] | None = None
    mode_shape_nodes: list[int] | None = None
    mode_shape_directions: list[str] | None = None
    mode_shape_xyz: list[list[Number]] | None = None
    n_lines_analysed: int | None = None
    reciprocity: bool | None = None
    mode_shape_channels: list[str] | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_dict(cls, obj: Any, where: str = "input") -> ReportInput:
        f = _Fields(obj, where)
        xyz = f.opt("output_xyz", _optional(_xyz_rows))
        return cls(
            path=f.req("path", _optional(_str)),
            sha256=f.req("sha256", _optional(_str)),
            n_freq=f.req("n_freq", _count),
            n_outputs=f.req("n_outputs", _count),
            n_inputs=f.req("n_inputs", _count),
            band_hz=f.req("band_hz", lambda x, w: _numbers(x, w, 2)),
            quantity=f.req("quantity", _str),
            output_names=f.req("output_names", _strings),
            input_names=f.req("input_names", _strings),
            attributes=f.req("attributes", _dict),
            frequency_range_hz=f.opt("frequency_range_hz", _numbers),
            output_xyz=xyz,
            output_directions=f.opt("output_directions", _optional(_strings)),
            mode_shape_nodes=f.opt("mode_shape_nodes", _optional(lambda x, w: [
                _int(v, f"{w}[{i}]") for i, v in enumerate(_list(x, w))])),
            mode_shape_directions=f.opt("mode_shape_directions", _optional(_strings)),
            mode_shape_xyz=f.opt("mode_shape_xyz", _optional(_xyz_rows)),
            n_lines_analysed=f.opt("n_lines_analysed", _count),
            reciprocity=f.opt("reciprocity", _bool),
            mode_shape_channels=f.opt("mode_shape_channels", _strings),
            extra=f.extra(),
        )

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "path": self.path,
            "sha256": self.sha256,
            "n_freq": self.n_freq,
            "n_outputs": self.n_outputs,
            "n_inputs": self.n_inputs,
            "band_hz": list(self.band_hz),
            "quantity": self.quantity,
            "output_names": list(self.output_names),
            "input_names": list(self.input_names),
            "attributes": dict(self.attributes),
        }
        _put(out, "frequency_range_hz", self.frequency_range_hz)
        out["output_xyz"] = self.output_xyz
        out["output_directions"] = self.output_directions
        _put(out, "mode_shape_nodes", self.mode_shape_nodes)
        _put(out, "mode_shape_directions", self.mode_shape_directions)
        _put(out, "mode_shape_xyz", self.mode_shape_xyz)
        _put(out, "n_lines_analysed", self.n_lines_analysed)
        _put(out, "reciprocity", self.reciprocity)
        _put(out, "mode_shape_channels", self.mode_shape_channels)
        out.update(self.extra)
        return out


@dataclass
class ReportSettings:
    """The ``settings`` section: every parameter that influenced the result.

    The keys are those of :meth:`automodal.settings.Settings.to_dict` plus ``orders`` (the
    order scan); they are kept as a dict (``values``) since they follow the pipeline.
    """

    values: dict[str, Any]

    @classmethod
    def from_dict(cls, obj: Any, where: str = "settings") -> ReportSettings:
        f = _Fields(obj, where)
        f.opt("seed", _int)
        f.opt("n_bootstrap", _optional(_count))
        f.opt("min_physicalness", _number)
        f.opt("orders", _optional(_dict))
        return cls(dict(obj))

    def to_dict(self) -> dict[str, Any]:
        return dict(self.values)

    def records(self, values: Mapping[str, Any]) -> bool:
        """Whether every one of ``values`` (plain JSON, e.g. ``json_safe(settings.to_dict())``)
        is recorded here with the same value."""
        return all(self.values.get(k) == v for k, v in values.items())

    @property
    def n_bootstrap(self) -> int | None:
        """Bootstrap replicates."""
        return self.values.get("n_bootstrap")

    @property
    def min_physicalness(self) -> float:
        """Physicalness from which a cluster is called physical (0.5 when not recorded)."""
        value = self.values.get("min_physicalness")
        return float(value) if _is_number(value) and value else 0.5


@dataclass
class ReportMode:
    """One element of ``modes``: a cluster (or one member rank of a near-repeated one).

    Numbers are ``None`` where the value was not finite. ``cluster``, ``cluster_dim`` and
    ``features`` are ``None`` when the report does not have them. ``mode_number`` numbers
    the physical modes 1, 2, ... by frequency (``None`` for a cluster not called physical);
    a report written before it existed gets it from ``physical`` when read
    (:meth:`Report.from_dict`).
    """

    id: int
    frequency_hz: Number
    frequency_std_hz: Number
    frequency_ci95_hz: list[Number]
    damping_ratio: Number
    damping_std: Number
    damping_ci95: list[Number]
    physicalness: Number
    physical: bool
    n_members: int
    shape_real: list[Number]
    shape_imag: list[Number]
    mode_shape_std: list[Number]
    mpc: Number
    cluster: int | None = None
    cluster_dim: int | None = None
    features: dict[str, Number] | None = None
    estimator: str | None = None
    mode_number: int | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_dict(cls, obj: Any, where: str) -> ReportMode:
        f = _Fields(obj, where)
        shape = _Fields(f.req("mode_shape", _dict), f"{where}.mode_shape")
        real = shape.req("real", _numbers)
        imag = shape.req("imag", lambda x, w: _numbers(x, w, len(real)))
        return cls(
            id=f.req("id", _int),
            frequency_hz=f.req("frequency_hz", _number),
            frequency_std_hz=f.req("frequency_std_hz", _number),
            frequency_ci95_hz=f.req("frequency_ci95_hz", lambda x, w: _numbers(x, w, 2)),
            damping_ratio=f.req("damping_ratio", _number),
            damping_std=f.req("damping_std", _number),
            damping_ci95=f.req("damping_ci95", lambda x, w: _numbers(x, w, 2)),
            physicalness=f.req("physicalness", _number),
            physical=f.req("physical", _bool),
            n_members=f.req("n_members", _count),
            shape_real=real,
            shape_imag=imag,
            mode_shape_std=f.req("mode_shape_std", _numbers),
            mpc=f.req("mpc", _number),
            cluster=f.opt("cluster", _int),
            cluster_dim=f.opt("cluster_dim", _count),
            features=f.opt("features", lambda x, w: {
                str(k): _number(v, f"{w}.{k}") for k, v in _dict(x, w).items()}),
            estimator=f.opt("estimator", _str),
            mode_number=f.opt("mode_number", _optional(_positive)),
            extra=f.extra(),
        )

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "id": self.id,
            "mode_number": self.mode_number,
            "frequency_hz": self.frequency_hz,
            "frequency_std_hz": self.frequency_std_hz,
            "frequency_ci95_hz": list(self.frequency_ci95_hz),
            "damping_ratio": self.damping_ratio,
            "damping_std": self.damping_std,
            "damping_ci95": list(self.damping_ci95),
            "physicalness": self.physicalness,
            "physical": self.physical,
            "n_members": self.n_members,
            "mode_shape": {"real": list(self.shape_real), "imag": list(self.shape_imag)},
            "mode_shape_std": list(self.mode_shape_std),
            "mpc": self.mpc,
        }
        _put(out, "cluster", self.cluster)
        _put(out, "cluster_dim", self.cluster_dim)
        _put(out, "features", None if self.features is None else dict(self.features))
        _put(out, "estimator", self.estimator)
        out.update(self.extra)
        return out

    @property
    def shape(self) -> np.ndarray:
        """The mode shape as a complex vector (NaN where an entry is ``null``)."""
        return as_floats(self.shape_real) + 1j * as_floats(self.shape_imag)

    @property
    def has_frequency(self) -> bool:
        """Whether the central frequency is known (finite)."""
        return self.frequency_hz is not None


@dataclass
class Trashbox:
    """The ``trashbox`` section: bootstrap poles in no cluster."""

    n_members: int
    extra: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_dict(cls, obj: Any, where: str = "trashbox") -> Trashbox:
        f = _Fields(obj, where)
        return cls(n_members=f.req("n_members", _count), extra=f.extra())

    def to_dict(self) -> dict[str, Any]:
        return {"n_members": self.n_members, **self.extra}


@dataclass
class ReportNoise:
    """The ``noise`` section: the noise model a run used (only when it used one, with
    ``settings.weighting = "noise"``): its ``source`` (``records``, ``coherence`` or
    ``data``), the relative noise level of each output channel, the number of averages the
    coherence law took, what was assumed, and the reference model's ``dispersion`` (its
    whitened residual over its degrees of freedom)."""

    source: str
    output_level: dict[str, Number]
    n_averages: Number | None = None
    assumptions: list[str] = field(default_factory=list)
    dispersion: Number = 1.0
    extra: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_dict(cls, obj: Any, where: str = "noise") -> ReportNoise:
        f = _Fields(obj, where)
        levels = f.req("output_level", _dict)
        return cls(
            source=f.req("source", _str),
            output_level={str(k): _number(v, f"{where}.output_level.{k}")
                          for k, v in levels.items()},
            n_averages=f.opt("n_averages", _optional(_number)),
            assumptions=f.opt("assumptions", _strings) or [],
            dispersion=f.opt("dispersion", _number) or 1.0,
            extra=f.extra(),
        )

    def to_dict(self) -> dict[str, Any]:
        return {"source": self.source, "output_level": dict(self.output_level),
                "n_averages": self.n_averages, "assumptions": list(self.assumptions),
                "dispersion": self.dispersion, **self.extra}


@dataclass
class ReportSummary:
    """The ``summary`` section.

    ``n_clusters`` counts the listed modes; ``n_reference_clusters`` (``None`` when the
    report does not have it) the clusters of the reference order.
    """

    n_physical: int
    n_clusters: int
    n_bootstrap: int | None
    runtime_s: Number
    n_reference_clusters: int | None = None
    frf_fit_error: list[list[Number]] | None = None
    """Normalised error of the FRF synthesis per channel (outputs x inputs), or ``None``."""
    extra: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_dict(cls, obj: Any, where: str = "summary") -> ReportSummary:
        f = _Fields(obj, where)
        return cls(
            n_physical=f.req("n_physical", _count),
            n_clusters=f.req("n_clusters", _count),
            n_bootstrap=f.req("n_bootstrap", _optional(_count)),
            runtime_s=f.req("runtime_s", _number),
            n_reference_clusters=f.opt("n_reference_clusters", _count),
            frf_fit_error=f.opt("frf_fit_error", lambda x, w: [
                _numbers(row, f"{w}[{i}]") for i, row in enumerate(_list(x, w))]),
            extra=f.extra(),
        )

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"n_physical": self.n_physical, "n_clusters": self.n_clusters,
                               "n_bootstrap": self.n_bootstrap, "runtime_s": self.runtime_s}
        _put(out, "n_reference_clusters", self.n_reference_clusters)
        _put(out, "frf_fit_error", self.frf_fit_error)
        out.update(self.extra)
        return out


@dataclass
class MonitoringBlock:
    """The ``monitoring`` section a baseline check adds (:mod:`automodal.app.monitoring`).

    Attributes
    ----------
    baseline : dict
        ``path``, ``created`` and ``input_sha256`` of the baseline report.
    flagged : bool
        Whether any mode raised the alarm.
    n_flagged : int
    thresholds : dict
        The thresholds applied (``Thresholds.to_dict()``).
    modes : list of dict
        One check per physical baseline mode, then one per new mode (``status``,
        ``flagged``, ``reasons``, ``message``, the frequencies, ...).
    extra : dict
        Keys of a later writer.
    """

    baseline: dict[str, Any]
    flagged: bool
    n_flagged: int
    thresholds: dict[str, Any]
    modes: list[dict[str, Any]]
    extra: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_dict(cls, obj: Any, where: str = "monitoring") -> MonitoringBlock:
        f = _Fields(obj, where)
        modes = f.req("modes", _list)
        for i, entry in enumerate(modes):
            e = _Fields(entry, f"{where}.modes[{i}]")
            e.req("status", _str)
            e.req("flagged", _bool)
            e.req("message", _str)
        return cls(
            baseline=f.req("baseline", _dict),
            flagged=f.req("flagged", _bool),
            n_flagged=f.req("n_flagged", _count),
            thresholds=f.req("thresholds", _dict),
            modes=modes,
            extra=f.extra(),
        )

    def to_dict(self) -> dict[str, Any]:
        return {"baseline": self.baseline, "flagged": self.flagged,
                "n_flagged": self.n_flagged, "thresholds": self.thresholds,
                "modes": self.modes, **self.extra}

    @property
    def flagged_messages(self) -> list[str]:
        """One readable line per flagged mode."""
        return [str(e["message"]) for e in self.modes if e["flagged"]]


@dataclass
class ReportArrays:
    """Arrays a report keeps outside its JSON content (HDF5 ``/poles`` and ``/frf``).

    Attributes
    ----------
    poles : PoleTable or dict or None
        Every bootstrap pole (``frequency_hz``, ``damping_ratio``, ``cluster`` with ``-1``
        for the Trashbox, ``replicate``).
    frf : (frequency, measured, synthesized) or dict or None
        The analysed band's FRFs.
    stabilization : StabilizationPoles or dict or None
        The poles of the order scan (``order``, ``frequency_hz``, ``damping_ratio``,
        ``stability``), for the stabilization diagram.
    """

    poles: PoleTable | Mapping[str, np.ndarray] | None = None
    frf: FRFArrays | Mapping[str, np.ndarray] | None = None
    stabilization: StabilizationPoles | Mapping[str, np.ndarray] | None = None


# ------------------------------------------------------------------------------ the report


@dataclass
class Report:
    """One identification report (``docs/report.md``, version 1).

    Attributes
    ----------
    header : ReportHeader
    input : ReportInput
    settings : ReportSettings
    modes : list of ReportMode
        Sorted by frequency (modes without a finite frequency last).
    trashbox : Trashbox
    summary : ReportSummary
    warnings : list of str
    monitoring : MonitoringBlock or None
        The block a baseline check adds (see :mod:`automodal.app.monitoring`).
    noise : ReportNoise or None
        The noise model, when the run used one.
    extra : dict
        Top-level keys of a later writer.
    arrays : ReportArrays
        Poles and FRFs for the plots; not part of the JSON content (nor of ``==``).
    """

    header: ReportHeader
    input: ReportInput
    settings: ReportSettings
    modes: list[ReportMode]
    trashbox: Trashbox
    summary: ReportSummary
    warnings: list[str]
    monitoring: MonitoringBlock | None = None
    noise: ReportNoise | None = None
    extra: dict[str, Any] = field(default_factory=dict)
    arrays: ReportArrays = field(default_factory=ReportArrays, compare=False, repr=False)

    # -------------------------------------------------------------------- making

    @classmethod
    def from_result(
        cls,
        result: Result,
        data: FRFData,
        input_path: str | os.PathLike[str] | None = None,
        sha256: str | None = None,
        created: str | None = None,
        warnings: Sequence[str] = (),
    ) -> Report:
        """The report of one run.

        Parameters
        ----------
        result : Result
            What :func:`automodal.pipeline.identify` returned for ``data``.
        data : FRFData
            The test that was identified.
        input_path : str or path-like, optional
            The file ``data`` was read from (``input.path``).
        sha256 : str, optional
            SHA-256 of that file's bytes (see :func:`automodal.io.report.build_report`).
        created : str, optional
            UTC ISO 8601 time of the report; default now.
        warnings : sequence of str
            Warnings to add after the run's own (e.g. that the input could not be hashed).

        Returns
        -------
        Report
            With ``arrays`` holding the run's poles and FRF fit. Every NaN or infinity
            of the run is ``None`` with a warning naming its field. The keys of
            ``docs/report.md`` plus these additions: ``input.frequency_range_hz`` (span
            of the whole input, while ``input.band_hz`` is the analysed band),
            ``input.output_xyz``, ``input.output_directions``, ``input.n_lines_analysed``,
            ``input.reciprocity``, ``input.mode_shape_channels``, ``settings.orders``
            (the order scan and the reference order), per mode ``cluster``,
            ``cluster_dim`` and ``features`` (the physicalness features),
            ``summary.n_reference_clusters`` and, when the run used a noise model,
            ``noise``. ``summary.n_clusters`` counts the listed modes (every surviving
            cluster, a near-repeated cluster once per member rank), so that
            ``n_physical`` of ``n_clusters`` compares like with like. Modes are sorted
            by frequency.
        """
        all_warnings = [str(w) for w in result.warnings] + [str(w) for w in warnings]
        freq = np.asarray(data.frequency, dtype=float)
        shape_names = [str(n) for n in (result.shape_channels or data.output_names)]
        modes = sorted(result.modes, key=frequency_key)
        raw = {
            "format": FORMAT_NAME,
            "version": FORMAT_VERSION,
            "automodal_version": str(result.automodal_version),
            "created": created or utc_now(),
            "input": {
                "path": None if input_path is None else os.fspath(input_path),
                "sha256": sha256,
                "n_freq": data.n_freq,
                "n_outputs": data.n_outputs,
                "n_inputs": data.n_inputs,
                "band_hz": list(result.band_hz),
                "quantity": data.quantity,
                "output_names": [str(n) for n in data.output_names],
                "input_names": [str(n) for n in data.input_names],
                "attributes": dict(data.attributes),
                "frequency_range_hz": [freq[0], freq[-1]] if freq.size else [],
                "output_xyz": (None if data.output_xyz is None
                               else np.asarray(data.output_xyz, float)),
                "output_directions": (None if data.output_directions is None
                                      else [str(d) for d in data.output_directions]),
                **shape_channel_geometry(data, shape_names, bool(result.reciprocity)),
                "n_lines_analysed": int(result.n_lines),
                "reciprocity": bool(result.reciprocity),
                "mode_shape_channels": shape_names,
            },
            "settings": {**result.settings, "orders": result.orders},
            "modes": [_mode_content(m) for m in modes],
            "trashbox": {"n_members": result.trashbox_members},
            "summary": {
                "n_physical": sum(1 for m in result.modes if m.physical),
                "n_clusters": len(result.modes),
                "n_bootstrap": result.settings.get("n_bootstrap"),
                "runtime_s": result.runtime_s,
                "n_reference_clusters": result.n_clusters,
                "frf_fit_error": (None if result.frf_fit_error is None
                                  else np.asarray(result.frf_fit_error, float)),
            },
            "warnings": all_warnings,
        }
        if result.noise is not None:
            raw["noise"] = result.noise.to_dict()
        non_finite: list[str] = []
        clean = json_safe(raw, "", non_finite)
        clean["warnings"].extend(non_finite_warnings(non_finite))
        report = cls.from_dict(clean)
        report.arrays = ReportArrays(poles=result.poles, frf=result.frf_fit,
                                     stabilization=result.stabilization)
        return report

    # -------------------------------------------------------------------- dict form

    @classmethod
    def from_dict(cls, report: Any) -> Report:
        """Check a parsed report and make the model of it.

        Raises
        ------
        InputError
            If it is not an automodal report of a version this reads, or a field is
            missing or of the wrong type (the message names the field, e.g.
            ``modes[2].frequency_hz``).
        """
        header = ReportHeader.from_dict(report)
        f = _Fields(report, "")
        f.taken.update(("format", "version", "automodal_version", "created"))
        modes = f.req("modes", _list)
        made = cls(
            header=header,
            input=ReportInput.from_dict(f.req("input", _dict)),
            settings=ReportSettings.from_dict(f.req("settings", _dict)),
            modes=_with_mode_numbers(
                [ReportMode.from_dict(m, f"modes[{i}]") for i, m in enumerate(modes)],
                numbered=all(isinstance(m, dict) and "mode_number" in m for m in modes)),
            trashbox=Trashbox.from_dict(f.req("trashbox", _dict)),
            summary=ReportSummary.from_dict(f.req("summary", _dict)),
            warnings=f.req("warnings", _strings),
            monitoring=f.opt("monitoring", _optional(MonitoringBlock.from_dict)),
            noise=f.opt("noise", _optional(ReportNoise.from_dict)),
            extra=f.extra(),
        )
        _check_shape_lengths(made)
        return made

    def to_dict(self) -> dict[str, Any]:
        """The JSON content of the report (what is written; see ``docs/report.md``)."""
        out = self.header.to_dict()
        out.update({
            "input": self.input.to_dict(),
            "settings": self.settings.to_dict(),
            "modes": [m.to_dict() for m in self.modes],
            "trashbox": self.trashbox.to_dict(),
            "summary": self.summary.to_dict(),
            "warnings": list(self.warnings),
        })
        if self.noise is not None:
            out["noise"] = self.noise.to_dict()
        if self.monitoring is not None:
            out["monitoring"] = self.monitoring.to_dict()
        out.update(self.extra)
        return out

    @classmethod
    def coerce(cls, report: Report | Mapping[str, Any]) -> Report:
        """``report`` itself, or the model of a report dict (checked by :meth:`from_dict`)."""
        return report if isinstance(report, Report) else cls.from_dict(dict(report))

    # -------------------------------------------------------------------- derived

    @property
    def created(self) -> str:
        """When the report was made (UTC ISO 8601)."""
        return self.header.created

    @property
    def shape_channels(self) -> list[str]:
        """The channels of the mode shapes: ``input.mode_shape_channels`` (the outputs the
        run kept, or the inputs when it used reciprocity), else ``input.output_names``."""
        return list(self.input.mode_shape_channels or self.input.output_names)

    def shape_output_indices(self) -> list[int]:
        """Indices into ``input.output_names`` of the outputs the shapes cover: those named
        in ``mode_shape_channels`` when the run left some out, else all outputs."""
        names = self.input.output_names
        kept = self.input.mode_shape_channels or []
        if 0 < len(kept) < len(names) and all(k in names for k in kept):
            return [names.index(k) for k in kept]
        return list(range(len(names)))

    @property
    def physical_modes(self) -> list[ReportMode]:
        """The modes called physical that have a finite frequency, by frequency."""
        modes = [m for m in self.modes if m.physical and m.has_frequency]
        return sorted(modes, key=lambda m: m.frequency_hz)

    @property
    def n_physical(self) -> int:
        """Number of modes called physical."""
        return sum(1 for m in self.modes if m.physical)

    @property
    def band_hz(self) -> tuple[float, float] | None:
        """The analysed band, or ``None`` when the report does not give a valid one."""
        band = self.input.band_hz
        if len(band) == 2 and None not in band and band[1] > band[0]:
            return float(band[0]), float(band[1])
        return None

    def test_time(self) -> tuple[str, str]:
        """When the report's test was made: ``(iso_time, source)``.

        The first of :data:`DATE_KEYS` in ``input.attributes`` that parses as ISO 8601 wins
        (source ``"test_date"``); otherwise the report's ``created`` (source ``"created"``).
        Times without a zone are taken as UTC; the result is UTC with a ``Z``.

        Raises
        ------
        ValueError
            If neither gives a time.
        """
        for key in DATE_KEYS:
            parsed = parse_time(self.input.attributes.get(key))
            if parsed is not None:
                return parsed, "test_date"
        parsed = parse_time(self.header.created)
        if parsed is None:
            raise ValueError("the report has neither a test date nor a valid 'created' time")
        return parsed, "created"

    def test_date(self) -> str | None:
        """The test's date from the input's attributes, or ``None``."""
        try:
            when, source = self.test_time()
        except ValueError:
            return None
        return when if source == "test_date" else None

    def mode_table(self) -> ModeTable:
        """The modes as arrays (:class:`automodal.core.matching.ModeTable`).

        ``numbers`` holds the mode numbers (0 for a cluster not called physical); ``null``
        numbers are NaN; a mode without ``cluster`` is alone in its own; when
        the modes' shapes differ in length the table has no shapes (width 0).
        """
        from automodal.core.matching import ModeTable

        modes = self.modes
        n = len(modes)
        shapes = [m.shape for m in modes]
        widths = {s.size for s in shapes}
        width = widths.pop() if len(widths) == 1 else 0
        if any(m.cluster is None for m in modes):
            cluster = -1 - np.arange(n)
        else:
            cluster = np.array([m.cluster for m in modes], dtype=int)
        return ModeTable(
            ids=np.array([m.id for m in modes], dtype=int),
            frequency_hz=as_floats([m.frequency_hz for m in modes]),
            frequency_std_hz=as_floats([m.frequency_std_hz for m in modes]),
            frequency_ci95_hz=as_floats([m.frequency_ci95_hz for m in modes]).reshape(n, 2),
            damping_ratio=as_floats([m.damping_ratio for m in modes]),
            damping_std=as_floats([m.damping_std for m in modes]),
            damping_ci95=as_floats([m.damping_ci95 for m in modes]).reshape(n, 2),
            physical=np.array([m.physical for m in modes], dtype=bool),
            shapes=(np.vstack(shapes).astype(complex) if n and width
                    else np.full((n, 0), np.nan, complex)),
            cluster=cluster.reshape(n),
            numbers=np.array([m.mode_number or 0 for m in modes], dtype=int),
        )


# ------------------------------------------------------------------------------ helpers


def _xyz_rows(x: Any, where: str) -> list[list[Number]]:
    """A list of ``[x, y, z]`` rows."""
    return [_numbers(row, f"{where}[{i}]", 3) for i, row in enumerate(_list(x, where))]


def shape_channel_geometry(
    data: FRFData, names: Sequence[str], reciprocal: bool
) -> dict[str, Any]:
    """``mode_shape_nodes``, ``mode_shape_directions`` and ``mode_shape_xyz`` of the
    channels ``names`` (the inputs under reciprocity, else the outputs), each ``None``
    unless the data give it for every one of them."""
    side = "input" if reciprocal else "output"
    channels = [str(n) for n in getattr(data, f"{side}_names")]
    rows = [channels.index(n) if n in channels else -1 for n in names]
    if -1 in rows:
        return {"mode_shape_nodes": None, "mode_shape_directions": None,
                "mode_shape_xyz": None}
    nodes = getattr(data, f"{side}_nodes")
    directions = getattr(data, f"{side}_directions")
    xyz = None if reciprocal else data.output_xyz
    return {
        "mode_shape_nodes": None if nodes is None else [int(nodes[i]) for i in rows],
        "mode_shape_directions": (None if directions is None
                                  else [str(directions[i]) for i in rows]),
        "mode_shape_xyz": (None if xyz is None
                           else np.asarray(xyz, float)[rows].tolist()),
    }


def _check_shape_lengths(report: Report) -> None:
    """Refuse a report whose physical modes' shapes are not one value per shape channel
    (``input.mode_shape_channels``, when it names them): the figures and the exports
    index shapes by channel (a shape cut to 2 of 6 channels was an internal error in
    ``plot`` and a ragged CSV from ``export``)."""
    channels = report.input.mode_shape_channels
    if not channels:
        return
    for i, mode in enumerate(report.modes):
        n = len(mode.shape_real)
        if mode.physical and n and n != len(channels):
            raise _refuse(f"modes[{i}].mode_shape", f"has {n} values for the"
                          f" {len(channels)} channels of input.mode_shape_channels")


def _with_mode_numbers(modes: list[ReportMode], numbered: bool) -> list[ReportMode]:
    """``modes`` with the physical ones numbered 1, 2, ... by frequency when the report
    did not number them (``numbered`` false: written before ``mode_number`` existed),
    as the pipeline numbers them (modes without a frequency last)."""
    if numbered:
        return modes
    from automodal.core.matching import mode_numbers

    numbers = mode_numbers(
        np.array([np.nan if m.frequency_hz is None else m.frequency_hz for m in modes]),
        np.array([bool(m.physical) for m in modes], dtype=bool))
    for m, number in zip(modes, numbers):
        m.mode_number = int(number) if number else None
    return modes


def as_floats(values: Sequence[Any]) -> np.ndarray:
    """A float array from the report's JSON numbers (nested lists too), ``None`` as NaN."""
    def fix(v: Any) -> Any:
        if isinstance(v, (list, tuple)):
            return [fix(x) for x in v]
        return np.nan if v is None else v

    return np.array(fix(list(values)), dtype=float)


def _mode_content(mode: IdentifiedMode) -> dict[str, Any]:
    """One element of ``modes`` before :func:`json_safe`."""
    shape, shape_std = unit_max(mode.mode_shape, mode.mode_shape_std)
    return {
        "id": mode.id,
        "mode_number": mode.mode_number,
        "frequency_hz": mode.frequency_hz,
        "frequency_std_hz": mode.frequency_std_hz,
        "frequency_ci95_hz": list(mode.frequency_ci95_hz),
        "damping_ratio": mode.damping_ratio,
        "damping_std": mode.damping_std,
        "damping_ci95": list(mode.damping_ci95),
        "physicalness": mode.physicalness,
        "physical": bool(mode.physical),
        "n_members": mode.n_members,
        "mode_shape": {"real": shape.real, "imag": shape.imag},
        "mode_shape_std": shape_std,
        "mpc": mode.mpc,
        "cluster": mode.cluster,
        "cluster_dim": mode.cluster_dim,
        "features": dict(mode.features),
        "estimator": mode.estimator,
    }


def unit_max(shape: np.ndarray, shape_std: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Scale a shape so that its largest finite-magnitude entry is exactly ``1 + 0j``.

    The spread is divided by the same magnitude. A shape already in this convention is
    returned unchanged; an all-zero or all-non-finite one is left as it is.
    """
    psi = np.asarray(shape, dtype=complex).ravel()
    spread = np.asarray(shape_std, dtype=float).ravel()
    if psi.size == 0:
        return psi, spread
    mag = np.abs(psi)
    k = int(np.argmax(np.where(np.isfinite(mag), mag, -1.0)))
    if not (np.isfinite(mag[k]) and mag[k] > 0) or psi[k] == 1:
        return psi, spread
    psi = psi / psi[k]
    psi[k] = 1.0
    return psi, spread / mag[k]


def frequency_key(mode: IdentifiedMode) -> tuple[bool, float]:
    """Sort key of the report's modes: by frequency, modes without a finite one last."""
    f = float(mode.frequency_hz)
    return (not math.isfinite(f), f if math.isfinite(f) else 0.0)


def utc_now() -> str:
    """The current UTC time as ISO 8601 with seconds and ``Z``."""
    return _dt.datetime.now(_dt.timezone.utc).strftime(_UTC_FORMAT)


def parse_time(value: Any) -> str | None:
    """An ISO 8601 text as UTC ``YYYY-MM-DDTHH:MM:SSZ`` (no zone: UTC), or ``None``."""
    if not isinstance(value, str) or not value.strip():
        return None
    text = value.strip()
    if text.endswith(("Z", "z")):
        text = text[:-1] + "+00:00"
    try:
        t = _dt.datetime.fromisoformat(text)
    except ValueError:
        return None
    if t.tzinfo is None:
        t = t.replace(tzinfo=_dt.timezone.utc)
    return t.astimezone(_dt.timezone.utc).strftime(_UTC_FORMAT)
