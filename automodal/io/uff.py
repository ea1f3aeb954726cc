"""Reading universal files (UFF/UNV), dataset 58, ASCII or binary, with pyuff: FRFs, or
time records.

Each dataset 58 holds one function between a response DOF (node and direction) and a
reference DOF. :func:`read_uff` groups FRF sets by reference (input) and response (output)
into one ``(n_freq, n_outputs, n_inputs)`` array, in the order in which the channels first
appear in the file. A file whose every set is a time response (function type 1) holds time
records instead: one channel per set, forces being the sets whose ordinate is an excitation
force (specific data type 13). Node coordinates (datasets 15 and 2411,
:mod:`automodal.io.uff_geometry`) in a file of FRFs place its outputs; data sets of other
types (units, ...) are skipped.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from automodal.errors import InputError
from automodal.frfdata import FRFData
from automodal.io.channels import Channels, frequency_unit_problem, rate_from_time
from automodal.io.limits import check_not_real_valued, check_text_size
from automodal.io.refusal import describe, read_refusing
from automodal.io.uff_geometry import Nodes, nodes_of_file, open_uff

__all__ = ["FUNCTION_TYPES", "direction_name", "read_uff"]

FRF_FUNCTION_TYPE = 4
"""Function type (record 6, field 1) of a frequency response function."""

TIME_FUNCTION_TYPE = 1
"""Function type of a time response (a record of samples)."""

_FORCE_TYPE = 13
"""Specific data type (records 8 to 11, field 1) of an excitation force."""

FUNCTION_TYPES = {
    0: "general or unknown", 1: "time response", 2: "auto spectrum", 3: "cross spectrum",
    4: "frequency response function", 5: "transmissibility", 6: "coherence",
    7: "auto correlation", 8: "cross correlation", 9: "power spectral density",
    10: "energy spectral density", 11: "probability density function", 12: "spectrum",
    13: "cumulative frequency distribution", 14: "peaks valley", 15: "stress/cycles",
    16: "strain/cycles", 17: "orbit", 18: "mode indicator function", 19: "force pattern",
    20: "partial power", 21: "partial coherence", 22: "eigenvalue", 23: "eigenvector",
    24: "shock response spectrum", 25: "finite impulse response filter",
    26: "multiple coherence", 27: "order function",
}
"""Names of the dataset 58 function types."""

_ORDINATE_TYPES = {2: "real, single precision", 4: "real, double precision",
                   5: "complex, single precision", 6: "complex, double precision"}
_REAL_ORDINATES = (2, 4)

_MOTION_TYPES = {8: "displacement", 11: "velocity", 12: "acceleration"}
"""Specific data types (records 8 to 11, field 1) that name a response quantity."""

_NOT_FREQUENCY_ABSCISSAS = {17: "time", 19: "rpm", 20: "order"}

_AXES = "XYZ"

# Units or names in the ordinate axis labels, tried in this order (spaces removed, lower case).
_LABEL_PATTERNS = (
    ("acceleration", re.compile(r"accel|inertance|/s(\^|\*\*)?2|/s²|/sec(\^|\*\*)?2|^g($|/)")),
    ("velocity", re.compile(r"veloc|mobility|/s($|/|\))|/sec($|/|\))")),
    ("displacement", re.compile(r"displ|receptance|compliance|^\(?(m|mm|µm|um|in)($|/|\))")),
)
# The FRF names alone, for the free-text ID lines.
_ID_PATTERNS = (
    ("acceleration", re.compile(r"accelerance|inertance")),
    ("velocity", re.compile(r"mobility")),
    ("displacement", re.compile(r"receptance|compliance")),
)


def read_uff(path: str | os.PathLike[str]) -> FRFData | Channels:
    """Read the FRFs, or the time records, of a universal file (dataset 58, ASCII or binary).

    A file whose every dataset 58 is a time response (function type 1) gives
    :class:`~automodal.io.channels.Channels`: see :func:`_time_channels`. Otherwise:

    Every dataset 58 must be an FRF (function type 4) with complex values over one common
    frequency axis (uneven spacing is fine when every set has the same lines). The sets are
    grouped by response DOF (output: response node and direction) and reference DOF
    (input: reference node and direction); every (output, input) pair must be present
    exactly once. A roving-hammer test (one response, many references) and a roving-sensor
    test (many responses, one reference) are complete by construction.

    The response quantity comes from the ordinate numerator's specific data type
    (8 displacement, 11 velocity, 12 acceleration), else from the ordinate axis labels or
    units (e.g. ``"m/s^2"``), else from the words accelerance/inertance, mobility,
    receptance/compliance in the ID lines; failing all that it is ``"displacement"``.
    ``attributes["quantity_source"]`` always says which it was.

    A line at 0 Hz that holds NaN or 0+0j in any FRF (a common placeholder for the DC line,
    which a measurement cannot give) is dropped, and ``attributes["dropped_0hz_line"]`` says
    so. Any other non-finite value is refused.

    When the file also holds node coordinates (datasets 15 or 2411, global cartesian), the
    outputs get theirs (``output_xyz``) by node number; every response and reference node
    must then be among them. ``attributes["geometry_source"]`` says so.

    Parameters
    ----------
    path : str or path-like
        The ``.uff`` or ``.unv`` file.

    Returns
    -------
    FRFData
        FRFs of shape ``(n_freq, n_outputs, n_inputs)``, with channel names
        (the entity names where they tell the channels apart, else node and direction such
        as ``"12+Z"``), node numbers and directions (``"+X"``, ``"-Z"``, ``"+RX"`` for a
        rotation, ``"scalar"``). ``attributes`` holds ``source_format`` and
        ``quantity_source`` (and ``dropped_0hz_line`` when that happened); ``source`` is
        ``str(path)``.

    Raises
    ------
    InputError
        One line naming the file, when the file is missing or unreadable (any pyuff error),
        holds no dataset 58, holds a function that is not an FRF (saying which type was
        found), real-valued data, sets over different frequency axes, a non-frequency
        abscissa, a ratio of motion to motion, sets that disagree on the response quantity,
        an (output, input) pair given twice or missing, or non-finite values; node
        coordinates that :func:`automodal.io.uff_geometry.nodes_of_file` refuses, or
        that lack a response or reference node; or when it is larger than
        :data:`automodal.io.limits.MAX_TEXT_BYTES` (not read).
    """
    return read_refusing(_read_uff, path)


def _read_uff(p: Path, source: str) -> FRFData | Channels:
    """:func:`read_uff` (raises :class:`InputError` naming ``source`` on a bad file)."""
    check_text_size(p, source)
    uff, types = open_uff(p, source)
    sets = _read_sets(uff, types, source)
    if all(int(dset.get("func_type", -1)) == TIME_FUNCTION_TYPE for _, dset in sets):
        return _time_channels(sets, source)
    for number, dset in sets:
        _check_set(number, dset, source)
    frequency = _common_frequency(sets, source)
    outputs, inputs, frf = _group(sets, frequency.size, source)
    quantity, quantity_source = _quantity(sets, source)
    attributes: dict[str, Any] = {
        "source_format": _format_name(sets),
        "quantity_source": quantity_source,
    }
    frequency, frf, dropped = _drop_placeholder_dc_line(frequency, frf)
    if dropped:
        attributes["dropped_0hz_line"] = dropped
    output_names, input_names = _channel_names(outputs, inputs)
    nodes = nodes_of_file(uff, types, source)
    if nodes is not None:
        attributes["geometry_source"] = "UFF datasets 15/2411 of the file"
    data = FRFData(
        frequency=frequency,
        frf=frf,
        quantity=quantity,
        output_names=output_names,
        input_names=input_names,
        output_nodes=np.array([c["node"] for c in outputs], dtype=np.int64),
        input_nodes=np.array([c["node"] for c in inputs], dtype=np.int64),
        output_directions=[direction_name(c["dir"]) for c in outputs],
        input_directions=[direction_name(c["dir"]) for c in inputs],
        output_xyz=None if nodes is None else _coordinates(nodes, outputs, inputs, source),
        attributes=attributes,
        source=source,
    )
    check_not_real_valued(data.frf, source)
    return data


def _coordinates(nodes: Nodes, outputs: list[dict[str, Any]],
                 inputs: list[dict[str, Any]], source: str) -> np.ndarray:
    """The outputs' coordinates from the file's own nodes; every response and reference
    node must be there."""
    for side, channels in (("response", outputs), ("reference", inputs)):
        for c in channels:
            if c["node"] not in nodes:
                raise InputError(
                    f"{side} node {c['node']} ({_dof(c)}) is not among the file's "
                    f"{len(nodes)} nodes of dataset 15/2411: add it there, or "
                    "remove those datasets and give --geometry", source)
    return np.array([nodes[c["node"]] for c in outputs], dtype=float)


def direction_name(code: int) -> str:
    """A UFF direction code as text.

    Parameters
    ----------
    code : int
        -6..6: 1, 2, 3 translations along X, Y, Z; 4, 5, 6 rotations about them; negative
        for the negative direction; 0 a scalar point.

    Returns
    -------
    str
        ``"+X"``, ``"-Z"``, ``"+RY"`` (rotation), ``"scalar"``, or ``"code N"`` for a code
        outside -6..6.
    """
    if code == 0:
        return "scalar"
    if not 1 <= abs(code) <= 6:
        return f"code {code}"
    sign = "+" if code > 0 else "-"
    axis = _AXES[(abs(code) - 1) % 3]
    return f"{sign}R{axis}" if abs(code) > 3 else f"{sign}{axis}"


# ----------------------------------------------------------------------------- reading


def _read_sets(uff: Any, types: list[int], source: str) -> list[tuple[int, dict[str, Any]]]:
    """All datasets 58 of the file as (1-based number of the set in the file, dict)."""
    wanted = [i for i, t in enumerate(types) if t == 58]
    if not wanted:
        found = sorted({t for t in types if t > 0})
        what = ("data sets of type " + ", ".join(map(str, found))) if found else "no UFF data set"
        raise InputError(f"no dataset 58 (function at nodal DOF) in the file; found {what}",
                         source)
    sets = []
    for i in wanted:
        try:
            dset = uff.read_sets(i)
        except Exception as exc:  # noqa: BLE001 - pyuff raises bare Exception
            raise InputError(f"cannot read data set {i + 1} (dataset 58): {describe(exc)}",
                             source) from exc
        sets.append((i + 1, dset))
    return sets


def _check_set(number: int, dset: dict[str, Any], source: str) -> None:
    """Refuse a set that is not a complex FRF over frequency."""
    func_type = int(dset.get("func_type", -1))
    if func_type != FRF_FUNCTION_TYPE:
        name = FUNCTION_TYPES.get(func_type, "unknown type")
        raise InputError(f"data set {number} is function type {func_type} ({name}), not "
                         f"{FRF_FUNCTION_TYPE} (frequency response function)", source)
    ord_type = int(dset.get("ord_data_type", -1))
    if ord_type in _REAL_ORDINATES:
        raise InputError(f"data set {number} holds real values (ordinate data type {ord_type}, "
                         f"{_ORDINATE_TYPES[ord_type]}); an FRF must be complex", source)
    abscissa = int(dset.get("abscissa_spec_data_type", 0))
    if abscissa in _NOT_FREQUENCY_ABSCISSAS:
        raise InputError(f"data set {number} has a {_NOT_FREQUENCY_ABSCISSAS[abscissa]} "
                         f"abscissa (data type {abscissa}), not frequency", source)
    problem = frequency_unit_problem(str(dset.get("abscissa_axis_units_lab", "") or ""))
    if problem:
        raise InputError(f"data set {number}: {problem}", source)
    denominator = int(dset.get("orddenom_spec_data_type", 0))
    if denominator in _MOTION_TYPES:
        raise InputError(f"data set {number} is per unit {_MOTION_TYPES[denominator]} "
                         f"(ordinate denominator data type {denominator}), not per unit "
                         "force", source)
    x, data = np.asarray(dset.get("x")), np.asarray(dset.get("data"))
    if x.ndim != 1 or data.shape != x.shape or x.size == 0:
        raise InputError(f"data set {number} is damaged: {x.size} abscissa values for "
                         f"{data.size} ordinate values", source)


def _common_frequency(sets: list[tuple[int, dict[str, Any]]], source: str) -> np.ndarray:
    """The frequency axis shared by every set (refuse sets over different axes)."""
    first_number, first = sets[0]
    ref = np.asarray(first["x"], dtype=np.float64)
    scale = float(np.max(np.abs(ref))) if np.all(np.isfinite(ref)) else 0.0
    for number, dset in sets[1:]:
        x = np.asarray(dset["x"], dtype=np.float64)
        if x.shape != ref.shape or not np.allclose(x, ref, rtol=1e-9, atol=1e-12 * scale):
            raise InputError(
                f"data set {number} has a different frequency axis ({_axis(x)}) from data set "
                f"{first_number} ({_axis(ref)}); all FRFs must share one axis", source)
    return ref


def _axis(x: np.ndarray) -> str:
    """A frequency axis in a few words."""
    return f"{x.size} lines, [{x[0]:g}, {x[-1]:g}] Hz"


# ---------------------------------------------------------------------------- grouping


def _group(
    sets: list[tuple[int, dict[str, Any]]], n_freq: int, source: str
) -> tuple[list[dict[str, Any]], list[dict[str, Any]], np.ndarray]:
    """Group the sets by (response DOF, reference DOF) into one FRF array.

    Returns the output channels, the input channels (dicts with ``node``, ``dir`` and
    ``entity``, in order of first appearance) and the FRF array.
    """
    outputs: dict[tuple[int, int], int] = {}
    inputs: dict[tuple[int, int], int] = {}
    out_info: list[dict[str, Any]] = []
    in_info: list[dict[str, Any]] = []
    cells: dict[tuple[int, int], int] = {}
    for number, dset in sets:
        i = _channel_index(outputs, out_info, dset, "rsp")
        j = _channel_index(inputs, in_info, dset, "ref")
        if (i, j) in cells:
            raise InputError(
                f"data sets {cells[i, j]} and {number} are both the FRF of output "
                f"{_dof(out_info[i])} for input {_dof(in_info[j])}", source)
        cells[i, j] = number
    missing = [(i, j) for i in range(len(out_info)) for j in range(len(in_info))
               if (i, j) not in cells]
    if missing:
        i, j = missing[0]
        raise InputError(
            f"{len(missing)} of the {len(out_info) * len(in_info)} (output, input) pairs have "
            f"no FRF, e.g. output {_dof(out_info[i])} for input {_dof(in_info[j])}; every "
            f"response must be measured for every reference", source)
    frf = np.empty((n_freq, len(out_info), len(in_info)), dtype=np.complex128)
    by_number = dict(sets)
    for (i, j), number in cells.items():
        frf[:, i, j] = np.asarray(by_number[number]["data"])
    return out_info, in_info, frf


def _channel_index(
    index: dict[tuple[int, int], int], info: list[dict[str, Any]], dset: dict[str, Any],
    prefix: str,
) -> int:
    """The index of the set's response (``prefix="rsp"``) or reference channel, adding it."""
    key = (int(dset.get(f"{prefix}_node", 0)), int(dset.get(f"{prefix}_dir", 0)))
    if key not in index:
        index[key] = len(info)
        entity = str(dset.get(f"{prefix}_ent_name", "") or "").strip()
        info.append({"node": key[0], "dir": key[1], "entity": entity})
    return index[key]


def _dof(channel: dict[str, Any]) -> str:
    """Node and direction of a channel, e.g. ``"12+Z"``."""
    direction = direction_name(channel["dir"])
    return str(channel["node"]) if direction == "scalar" else f"{channel['node']}{direction}"


def _channel_names(
    outputs: list[dict[str, Any]], inputs: list[dict[str, Any]]
) -> tuple[list[str], list[str]]:
    """Names of the output and input channels.

    The entity names of record 6 are used when every DOF of the file has one (not
    ``NONE``) and no two DOFs share one; otherwise (e.g. one test name written into every
    set) the names are node and direction, such as ``"12+Z"``.
    """
    entity_of = {(c["node"], c["dir"]): c["entity"] for c in outputs + inputs}
    entities = list(entity_of.values())
    usable = all(e and e.upper() != "NONE" for e in entities)
    if usable and len(set(entities)) == len(entities):
        return [c["entity"] for c in outputs], [c["entity"] for c in inputs]
    return [_dof(c) for c in outputs], [_dof(c) for c in inputs]


# ---------------------------------------------------------------------------- quantity


def _quantity(sets: list[tuple[int, dict[str, Any]]], source: str) -> tuple[str, str]:
    """The response quantity of the sets and a note saying where it came from."""
    found = [(number, *_set_quantity(dset)) for number, dset in sets]
    known = [(number, q, why) for number, q, why in found if q is not None]
    if not known:
        return "displacement", ("not stated in the UFF file (no response data type, axis "
                                "label or FRF name); assumed displacement (receptance)")
    n_first, quantity, why = known[0]
    for number, q, _ in known[1:]:
        if q != quantity:
            raise InputError(f"the data sets disagree on the response quantity: data set "
                             f"{n_first} is {quantity}, data set {number} is {q}", source)
    note = f"{why} of data set {n_first}"
    if len(known) < len(sets):
        note += f"; {len(sets) - len(known)} of {len(sets)} sets do not say, assumed the same"
    return quantity, note


def _set_quantity(dset: dict[str, Any]) -> tuple[str | None, str]:
    """The response quantity one set states, and how it states it (None when it does not)."""
    code = int(dset.get("ordinate_spec_data_type", 0))
    if code in _MOTION_TYPES:
        return _MOTION_TYPES[code], f"ordinate data type {code} ({_MOTION_TYPES[code]})"
    for key in ("ordinate_axis_units_lab", "ordinate_axis_lab"):
        label = _text(dset.get(key))
        quantity = _match(_LABEL_PATTERNS, label, first_wins=True)
        if quantity:
            return quantity, f"ordinate axis label {dset.get(key)!r}"
    for k in range(1, 6):
        quantity = _match(_ID_PATTERNS, _text(dset.get(f"id{k}")), first_wins=False)
        if quantity:
            return quantity, f"ID line {k} {dset.get(f'id{k}')!r}"
    return None, ""


def _text(value: Any) -> str:
    """A header string, lower case without spaces ("" for NONE or nothing)."""
    text = "".join(str(value or "").split()).lower()
    return "" if text == "none" else text


def _match(patterns: tuple[tuple[str, re.Pattern[str]], ...], text: str,
           first_wins: bool) -> str | None:
    """The quantity whose pattern matches ``text``.

    With ``first_wins`` the first matching pattern decides (the label patterns are ordered
    most specific first); otherwise a text that matches several quantities says nothing.
    """
    hits = [quantity for quantity, pattern in patterns if pattern.search(text)] if text else []
    if not hits or (len(hits) > 1 and not first_wins):
        return None
    return hits[0]


# ------------------------------------------------------------------------------ others


def _drop_placeholder_dc_line(
    frequency: np.ndarray, frf: np.ndarray
) -> tuple[np.ndarray, np.ndarray, str]:
    """Drop a 0 Hz line that holds NaN or 0+0j in some FRF; return a note when dropped."""
    if frequency.size < 2 or frequency[0] != 0.0:
        return frequency, frf, ""
    line = frf[0]
    placeholder = np.isnan(line) | (line == 0)
    if not placeholder.any():
        return frequency, frf, ""
    note = (f"the 0 Hz line was dropped: {int(placeholder.sum())} of {line.size} FRFs hold "
            "NaN or 0+0j there")
    return frequency[1:], frf[1:], note


def _format_name(sets: list[tuple[int, dict[str, Any]]]) -> str:
    """``"UFF dataset 58 (ASCII)"``, ``"... (binary)"`` or ``"... (ASCII and binary)"``."""
    kinds = {"binary" if dset.get("binary") else "ASCII" for _, dset in sets}
    return f"UFF dataset 58 ({' and '.join(sorted(kinds))})"


# -------------------------------------------------------------------------- time records


def _time_channels(sets: list[tuple[int, dict[str, Any]]], source: str) -> Channels:
    """The channels of a file of time responses (function type 1), one per set.

    Every set must hold real values over one common time axis (uniform: it gives the sample
    rate) and be the only one of its response DOF. A set whose ordinate is an excitation
    force (specific data type 13) is a force; when some set states its ordinate type, the
    file says which channels are forces, else ``--forces`` must. The response quantity is
    the responses' ordinate type (or axis label), when they state one and agree.
    """
    first_number, first = sets[0]
    x = np.asarray(first.get("x"), dtype=np.float64)
    for number, dset in sets:
        ord_type = int(dset.get("ord_data_type", -1))
        if ord_type not in _REAL_ORDINATES:
            name = _ORDINATE_TYPES.get(ord_type, "unknown")
            raise InputError(f"data set {number} is a time response with ordinate data type "
                             f"{ord_type} ({name}); samples must be real", source)
        abscissa = int(dset.get("abscissa_spec_data_type", 0))
        if abscissa not in (0, 17):
            raise InputError(f"data set {number} is a time response over an abscissa of data "
                             f"type {abscissa}, not time (17)", source)
        xs, data = np.asarray(dset.get("x"), dtype=np.float64), np.asarray(dset.get("data"))
        if data.shape != x.shape or xs.shape != x.shape or not np.allclose(xs, x, rtol=1e-9):
            raise InputError(f"data set {number} has another time axis ({xs.size} samples) "
                             f"than data set {first_number} ({x.size}): all records must "
                             "be sampled together", source)
    rate = rate_from_time(x, f"the time axis of data set {first_number}")
    channels: dict[tuple[int, int], int] = {}
    info: list[dict[str, Any]] = []
    for number, dset in sets:
        key = (int(dset.get("rsp_node", 0)), int(dset.get("rsp_dir", 0)))
        if key in channels:
            raise InputError(f"data sets {channels[key]} and {number} are both records of "
                             f"{_dof({'node': key[0], 'dir': key[1]})}", source)
        channels[key] = number
        _channel_index({}, info, dset, "rsp")
    names, _ = _channel_names(info, [])
    types = [int(dset.get("ordinate_spec_data_type", 0)) for _, dset in sets]
    says = any(t == _FORCE_TYPE or t in _MOTION_TYPES for t in types)
    forces = [i for i, t in enumerate(types) if t == _FORCE_TYPE] if says else None
    responses = [s for s, t in zip(sets, types) if t != _FORCE_TYPE]
    quantity = None  # unless a response states it: then the sets must agree
    if any(_set_quantity(dset)[0] is not None for _, dset in responses):
        quantity, _ = _quantity(responses, source)
    samples = np.column_stack([np.asarray(dset["data"], dtype=np.float64) for _, dset in sets])
    return Channels(samples=samples, names=names, sample_rate=rate,
                    rate_source=f"the time axis of data set {first_number}", forces=forces,
                    quantity=quantity,
                    attributes={"source_format": _format_name(sets).replace(
                        "dataset 58", "dataset 58 time records")})
