"""Reading plain tables: CSV/text files (FRFs or samples) and NumPy ``.npz`` archives of FRFs.

:func:`read_table` reads a table of FRFs or of samples, as its header says (a first column
named like a frequency, or FRF parts: FRFs; a column named like a time, or channel names
with a given sample rate: samples, ``docs/time-input.md``); :func:`read_csv` reads FRFs.

CSV layout (:func:`read_csv`)::

    # quantity: acceleration            <- optional; see below
    frequency, H1_re, H1_im, H2_re, H2_im   <- optional header
    1.0, 0.12, -0.03, 0.40, 0.01
    2.0, ...

One row per frequency line; the first column is the frequency in Hz, then one (real,
imaginary) column pair per FRF. Each pair is one output of a single input, so the result has
``n_outputs`` = number of pairs and ``n_inputs`` = 1 (a roving-sensor or single-reference
test). Columns are separated by commas or by whitespace. A header may instead name a pair
(magnitude, phase) or (dB, phase), e.g. ``f, tip_mag, tip_phase_deg``: the phase's unit
(``deg`` or ``rad``) must be in its name. A pair the header names otherwise (``mag`` beside
``im``, a phase without a unit) is refused rather than guessed.

NPZ layout (:func:`read_npz`): ``frequency`` (1-D, Hz), ``frf`` (complex, shape
``(lines, outputs, inputs)``, or ``(lines, outputs)`` for one input), optional ``quantity``
(a string).
"""

from __future__ import annotations

import gzip
import math
import os
import re
import zlib
from collections.abc import Sequence
from pathlib import Path
from tokenize import TokenError
from typing import IO, Any

import numpy as np

from automodal.errors import InputError
from automodal.frfdata import QUANTITIES, FRFData, quantity_problem
from automodal.io.channels import (
    Channels,
    TimeOptions,
    frequency_unit_problem,
    rate_from_time,
    time_axis,
    time_unit,
)
from automodal.io.limits import (
    MAX_TEXT_BYTES,
    check_not_real_valued,
    check_size,
    check_text_size,
)
from automodal.io.refusal import describe, read_refusing

__all__ = ["NPZ_KEYS", "NPZ_LAYOUT", "holds_number_rows", "is_gzip_name", "npy_shape",
           "npz_frfdata", "npz_members", "read_csv", "read_npz", "read_table"]

_QUANTITY_LINE = re.compile(r"^#\s*quantity\s*[:=]\s*(\S+)\s*$", re.IGNORECASE)
_REAL_WRAPPED = re.compile(r"^re(al)?\s*[(\[](.*)[)\]]$", re.IGNORECASE)
_CSV_LAYOUT = "expected a frequency column, then one real and one imaginary column per FRF"
NPZ_LAYOUT = ("expected keys 'frequency' (1-D, Hz) and 'frf' (complex, shape (lines, outputs, "
               "inputs) or (lines, outputs)), and optionally 'quantity'")


def _assumed(kind: str) -> str:
    """The quantity note of a file that does not state its quantity."""
    return f"not stated in the {kind} file; assumed displacement (receptance)"


# --------------------------------------------------------------------------------- CSV


def read_csv(path: str | os.PathLike[str]) -> FRFData:
    """Read FRFs from a CSV or whitespace-separated text table.

    The first column is the frequency in Hz; the others come in (real, imaginary) pairs,
    one pair per FRF. All FRFs belong to one input: the result has one output per column
    pair and a single input. A first row that is not numeric is a header: it says what each
    pair holds, (real, imaginary) (``_re``/``_im`` or ``Re(...)``/``Im(...)``, or names that
    say neither), (magnitude, phase) or (dB, phase) (``mag``, ``dB``, ``phase_deg``,
    ``phase_rad``; a phase must state its unit), and the name of each pair's first column,
    without those words, becomes the output's name. ``attributes["csv_columns"]`` says how
    the columns were read. Blank lines and lines starting with ``#`` are skipped; a comment line
    ``# quantity: acceleration`` (or ``velocity``, ``displacement``) states the response
    quantity, which is otherwise ``"displacement"``. ``attributes["quantity_source"]`` says
    which.

    Parameters
    ----------
    path : str or path-like
        The ``.csv`` or ``.txt`` file (UTF-8).

    Returns
    -------
    FRFData
        FRFs of shape ``(n_freq, n_pairs, 1)``; ``source`` is ``str(path)``.

    Raises
    ------
    InputError
        One line naming the file, when the file is missing or not text, has no data rows,
        a value that is not a number, rows of different lengths, not an odd number (at least
        3) of columns, a header whose pairs are not (real, imaginary), (magnitude, phase) or
        (dB, phase), a phase without a unit, a negative magnitude, an unknown quantity, or
        breaks the rules of the FRF file (frequencies strictly increasing, >= 0; finite
        values; not all imaginary parts zero); or when it is larger than
        :data:`automodal.io.limits.MAX_TEXT_BYTES` (not read).
    """
    data = read_table(path)
    if not isinstance(data, FRFData):
        raise InputError("the header names a time column: a table of samples, not of FRFs "
                         "(read it with read_table)", str(path))
    return data


def read_table(path: str | os.PathLike[str],
               options: TimeOptions | None = None) -> FRFData | Channels:
    """Read a CSV or text table of FRFs or of samples, as its header says.

    The header decides: a first column named like a frequency (``f``, ``freq``,
    ``frequency``, ``Hz``, with or without a unit) or columns named as FRF parts (``_re``,
    ``_im``, ``mag``, ``phase_deg``, ...) make a table of FRFs (:func:`read_csv`); a column
    named like a time (``t``, ``time``, ``time [s]``, ``t_ms``) makes a table of samples, the
    other columns being channels named by the header, the rate derived from the time column
    (checked to be uniform). A header of channel names only is a table of samples when the
    sample rate is given (``options.sample_rate``) and is refused otherwise, since it could be
    either; a table without a header is a table of FRFs.

    Parameters
    ----------
    path : str or path-like
        The ``.csv``, ``.tsv`` or ``.txt`` file (UTF-8).
    options : TimeOptions, optional
        What the user says about samples (only whether a sample rate is given matters here).

    Returns
    -------
    FRFData or Channels
        The FRFs, or the channels of samples (with ``quantity`` when a ``# quantity:``
        comment states it) for :func:`automodal.io.channels.to_time_series`.

    Raises
    ------
    InputError
        What :func:`read_csv` refuses, and for a table of samples: an ambiguous header, two
        time columns, a time column that does not increase uniformly, no channel.
    """
    return read_refusing(lambda p, s: _read_table(p, s, options), path)


def _read_table(path: Path, source: str, options: TimeOptions | None) -> FRFData | Channels:
    """:func:`read_table` (raises :class:`InputError` naming ``source`` on a bad file)."""
    text = _read_text(path, source)
    quantity, quantity_source = "displacement", _assumed("CSV")
    stated = None
    rows: list[tuple[int, str]] = []
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        directive = _QUANTITY_LINE.match(line)
        if directive:
            given = _known_quantity(directive.group(1), f"line {number}", source)
            if stated is not None and given != stated:
                raise InputError(f"line {number}: '# quantity: {given}' contradicts the"
                                 f" {quantity_source}, '{stated}': keep one", source)
            quantity = stated = given
            quantity_source = f"'# quantity:' comment (line {number}) of the CSV file"
        elif line and not line.startswith("#"):
            rows.append((number, line))
    if not rows:
        raise InputError(f"no data rows; {_CSV_LAYOUT}", source)
    preamble, rows = _preamble(rows)
    if not rows and len(preamble) > 1:  # no line of numbers: say which line is not one
        _number_table([(n, _split(line, "," in line)) for n, line in preamble[1:]], source)
    comma = "," in rows[0][1] if rows else "," in preamble[-1][1]
    cells = [(n, _split(line, comma)) for n, line in rows]
    header = _header_of(preamble, cells, comma)
    table = _number_table(cells, source)
    if stated is None:
        units = _quantity_from_units(preamble, source)
        if units is not None:
            quantity, quantity_source = units
    n_cols = table.shape[1]
    if header is not None and len(header) != n_cols:
        raise InputError(f"the header has {len(header)} columns but the rows have {n_cols}",
                         source)
    if header is not None and _holds_samples(header, options, source):
        return _samples_table(table, header, stated)
    if header is not None and (problem := frequency_unit_problem(header[0])):
        raise InputError(problem, source)
    if n_cols < 3 or n_cols % 2 == 0:
        raise InputError(f"{n_cols} columns; {_CSV_LAYOUT} (an odd number of columns, at "
                         "least 3)", source)
    if header is None:
        frf = (table[:, 1::2] + 1j * table[:, 2::2])[:, :, np.newaxis]
        names: list[str] = []
        layout = "real, imaginary (no header)"
    else:
        frf, names, layout = _columns_by_header(table, header, source)
    data = FRFData(frequency=table[:, 0], frf=frf, quantity=quantity, output_names=names,
                   attributes={"source_format": "CSV table", "quantity_source": quantity_source,
                               "csv_columns": layout},
                   source=source)
    if len(preamble) > 1:
        data.attributes["csv_preamble"] = (f"{len(preamble) - (header is not None)} line(s) "
                                           "before the data left out")
    check_not_real_valued(data.frf, source)
    return data


_FREQUENCY_NAME = re.compile(r"^(f|freq|frequency|hz)\s*(?:[\[(]?\s*hz\s*[\])]?)?$",
                             re.IGNORECASE)


def _holds_samples(header: list[str], options: TimeOptions | None, source: str) -> bool:
    """Whether a table's header makes it one of samples (else FRFs); refuse an ambiguous
    one."""
    if any(time_unit(name) is not None for name in header):
        return True
    if _FREQUENCY_NAME.match(header[0].strip().replace("_", " ")):
        return False
    if any(_column_kind(name) != "other" for name in header[1:]):
        return False
    if options is not None and options.sample_rate is not None:
        return True
    raise InputError("the header names neither a frequency column (FRFs: name the first "
                     "column 'frequency') nor a time column (samples: name it 't' or 'time'); "
                     "for channels of samples without a time column give --sample-rate HZ",
                     source)


def _samples_table(table: np.ndarray, header: list[str], quantity: str | None) -> Channels:
    """The channels of a table of samples (a time column, if any, gives the rate)."""
    position, keep = time_axis([time_unit(name) is not None for name in header], header,
                               "the table")
    rate, rate_source = None, ""
    if position is not None:
        where = f"the time column {header[position]!r}"
        unit = time_unit(header[position]) or 1.0
        rate, rate_source = rate_from_time(table[:, position] * unit, where), where
    names = [header[i].strip() or f"ch{i}" for i in keep]
    return Channels(samples=table[:, keep], names=names, positions=keep, sample_rate=rate,
                    rate_source=rate_source, quantity=quantity,
                    attributes={"source_format": "CSV table of samples"},
                    time_position=position)


def _read_text(path: Path, source: str) -> str:
    """The file as text: UTF-8 (a leading byte-order mark removed), else Latin-1 (what
    Windows acquisition software writes, e.g. ``(m/s\xb2)``); a ``.gz`` file is unpacked
    first. Refuse bytes that are no text (a NUL byte)."""
    check_text_size(path, source)
    try:
        raw = _gunzipped(path, source) if is_gzip_name(path) else path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read the file: {exc.strerror or exc}", source) from exc
    if b"\x00" in raw:
        raise InputError(f"not a text file (UTF-8 or Latin-1); {_CSV_LAYOUT}", source)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def holds_number_rows(path: str | os.PathLike[str], max_bytes: int = 1 << 16) -> bool:
    """Whether a text file has a row of numbers (at least two) in its first ``max_bytes``:
    a table, unlike a ``readme.txt`` or notes kept beside the data. A file that cannot be
    read counts as a table (the reader then says what is wrong with it).

    Parameters
    ----------
    path : str or path-like
        The ``.txt``/``.csv``/``.tsv`` file, or its ``.gz``.
    max_bytes : int
        How much of the (unpacked) file to look at.

    Returns
    -------
    bool
    """
    try:
        if is_gzip_name(path):
            with gzip.open(path, "rb") as fh:
                head = fh.read(max_bytes)
        else:
            with open(path, "rb") as fh:
                head = fh.read(max_bytes)
    except (OSError, EOFError, zlib.error):
        return True
    lines = head.decode("latin-1").splitlines()
    if len(head) == max_bytes and len(lines) > 1:
        lines = lines[:-1]  # the last line may be cut short
    for line in lines:
        line = line.strip()
        if line and not line.startswith("#"):
            cells = _split(line, "," in line)
            if len(cells) >= 2 and _numeric(cells):
                return True
    return False


def is_gzip_name(path: str | os.PathLike[str]) -> bool:
    """Whether a file's name ends in ``.gz`` (any case)."""
    return str(path).lower().endswith(".gz")


def _gunzipped(path: Path, source: str) -> bytes:
    """The unpacked bytes of a gzip file, refused when they exceed the text limit."""
    try:
        with gzip.open(path, "rb") as fh:
            raw = fh.read(MAX_TEXT_BYTES + 1)
    except (gzip.BadGzipFile, EOFError, zlib.error) as exc:
        raise InputError(f"not a readable gzip file ({exc})", source) from None
    if len(raw) > MAX_TEXT_BYTES:
        raise InputError(f"unpacks to more than the {MAX_TEXT_BYTES} bytes a text reader "
                         "parses (too large to read safely)", source)
    return raw


def _preamble(rows: list[tuple[int, str]]) -> tuple[list[tuple[int, str]],
                                                   list[tuple[int, str]]]:
    """The lines before the first row of numbers (a header, and in exports of acquisition
    software such as SignalCalc also title, channel and unit lines), and the rows from it
    on."""
    for k, (_, line) in enumerate(rows):
        if _numeric(_split(line, "," in line)):
            return rows[:k], rows[k:]
    return rows, []


def _header_of(preamble: list[tuple[int, str]], cells: list[tuple[int, list[str]]],
               comma: bool) -> list[str] | None:
    """The header among the lines before the data: the one such line, or else the last one
    with as many cells as the data rows (the column names; title and unit lines around it
    are left out); ``None`` when there is none."""
    if len(preamble) == 1 or (preamble and not cells):
        return _split_header(preamble[-1][1], comma)
    width = len(cells[0][1]) if cells else 0
    for _, line in reversed(preamble):
        header = _split_header(line, comma)
        if len(header) == width:
            return header
    return None


_UNIT_QUANTITIES = (
    ("acceleration", re.compile(r"m\s*/\s*s\s*(?:\xb2|\^\s*2|\*\*\s*2|2)|\(g\)|\bg\s*/\s*n\b",
                                re.IGNORECASE)),
    ("velocity", re.compile(r"m\s*/\s*s(?!\s*(?:\xb2|\^|\*\*|2))", re.IGNORECASE)),
    ("displacement", re.compile(r"\(m\)\s*/?\s*\(n\)|\bm\s*/\s*n\b", re.IGNORECASE)),
)


def _quantity_from_units(preamble: list[tuple[int, str]],
                         source: str) -> tuple[str, str] | None:
    """The response quantity that the unit lines before the data state (``(m/s\xb2)(N)``:
    acceleration), with where it was read; ``None`` when they state none. Units of several
    quantities are refused: which one the FRFs are is not known."""
    found = {}
    for number, line in preamble:
        for quantity, pattern in _UNIT_QUANTITIES:
            match = pattern.search(line)
            if match and quantity not in found:
                found[quantity] = f"the unit {match.group(0)!r} on line {number} of the text file"
                break
    if len(found) > 1:
        raise InputError(f"{' and '.join(found.values())} are units of different quantities"
                         f" ({', '.join(found)}): add a comment line '# quantity: ...' that says"
                         " which the FRFs are", source)
    if not found:
        return None
    quantity, where = next(iter(found.items()))
    return quantity, where


def _split_header(line: str, comma: bool) -> list[str]:
    """The cells of the header row: split at commas, or at tabs when it has tabs (names may
    hold spaces, ``Time (s)``), or at whitespace."""
    if not comma and "\t" in line:
        return [cell.strip() for cell in line.split("\t") if cell.strip()]
    return _split(line, comma)


def _split(line: str, comma: bool) -> list[str]:
    """The cells of one row: split at commas, or at whitespace."""
    return [cell.strip() for cell in line.split(",")] if comma else line.split()


def _numeric(cells: list[str]) -> bool:
    """Whether every cell is a number."""
    try:
        for cell in cells:
            float(cell)
    except ValueError:
        return False
    return True


def _number_table(cells: list[tuple[int, list[str]]], source: str) -> np.ndarray:
    """The data rows as a 2-D float array; refuse non-numbers and ragged rows."""
    if not cells:
        raise InputError(f"a header but no data rows; {_CSV_LAYOUT}", source)
    first_line, first = cells[0]
    values = []
    for number, row in cells:
        if len(row) != len(first):
            raise InputError(f"line {number} has {len(row)} columns but line {first_line} has "
                             f"{len(first)}", source)
        try:
            values.append([float(cell) for cell in row])
        except ValueError:
            bad = next(cell for cell in row if not _numeric([cell]))
            raise InputError(f"line {number}: {bad!r} is not a number (columns must be "
                             "separated by commas or whitespace)", source) from None
    return np.array(values, dtype=np.float64)


_TOKENS = re.compile(r"[a-z]+|°", re.IGNORECASE)
_REAL_WORDS = {"re", "real"}
_IMAG_WORDS = {"im", "imag", "imaginary"}
_MAG_WORDS = {"mag", "magnitude", "abs", "amp", "amplitude", "modulus"}
_PHASE_WORDS = {"phase", "angle"}
_DEG_WORDS = {"deg", "degree", "degrees", "°"}
_RAD_WORDS = {"rad", "radian", "radians"}
_KIND_WORDS = (_REAL_WORDS | _IMAG_WORDS | _MAG_WORDS | _PHASE_WORDS | _DEG_WORDS
               | _RAD_WORDS | {"db"})
_PAIRS = "(real, imaginary), (magnitude, phase) or (dB, phase)"


def _column_kind(name: str) -> str:
    """What a column's header says it holds: ``re``, ``im``, ``mag``, ``db``,
    ``phase_deg``, ``phase_rad``, ``phase`` (no unit) or ``other``."""
    words = {w.lower() for w in _TOKENS.findall(name)}
    if words & _PHASE_WORDS:
        if words & _DEG_WORDS:
            return "phase_deg"
        return "phase_rad" if words & _RAD_WORDS else "phase"
    if "db" in words:
        return "db"
    if words & _MAG_WORDS:
        return "mag"
    if words & _REAL_WORDS or _REAL_WRAPPED.match(name.strip()):
        return "re"
    if words & _IMAG_WORDS:
        return "im"
    return "other"


def _columns_by_header(table: np.ndarray, header: list[str],
                       source: str) -> tuple[np.ndarray, list[str], str]:
    """The FRFs ``(lines, pairs, 1)``, output names and a description of the columns, read
    by what the header names each column pair: (real, imaginary) (also when the header does
    not say), (magnitude, phase) or (dB, phase), phase in degrees or radians as its header
    says. Any other pairing is refused: guessing would misread the data silently."""
    frf = np.empty((table.shape[0], (table.shape[1] - 1) // 2), dtype=complex)
    names, kinds = [], set()
    for k in range(frf.shape[1]):
        first, second = header[1 + 2 * k], header[2 + 2 * k]
        a, b = _column_kind(first), _column_kind(second)
        x, y = table[:, 1 + 2 * k], table[:, 2 + 2 * k]
        where = f"columns {2 + 2 * k} and {3 + 2 * k} ({first!r}, {second!r})"
        if (a, b) in {("re", "im"), ("other", "other"), ("re", "other"), ("other", "im")}:
            frf[:, k] = x + 1j * y
            kinds.add("real, imaginary")
        elif a in ("mag", "db") and b.startswith("phase"):
            if b == "phase":
                raise InputError(f"{where}: the phase's unit is not stated; name the column "
                                 "e.g. 'phase_deg' or 'phase_rad'", source)
            if a == "mag" and np.any(x < 0):
                raise InputError(f"{where}: a negative magnitude; is the column in dB? "
                                 "name it e.g. 'mag_dB'", source)
            magnitude = 10.0 ** (x / 20.0) if a == "db" else x
            phase = np.deg2rad(y) if b == "phase_deg" else y
            frf[:, k] = magnitude * np.exp(1j * phase)
            kinds.add(("dB" if a == "db" else "magnitude") + ", phase in "
                      + ("degrees" if b == "phase_deg" else "radians"))
        else:
            raise InputError(f"{where} are not a {_PAIRS} pair; rename the header's columns "
                             "or remove the header (then they are read as real, imaginary)",
                             source)
        names.append(_output_name(first, k))
    return frf[:, :, np.newaxis], names, "; ".join(sorted(kinds)) + " (from the header)"


def _output_name(first_header: str, k: int) -> str:
    """An output's name from the header of its pair's first column: without the words that
    say what the column holds (``re``, ``mag``, ``dB``, units) and bracketed units."""
    wrapped = _REAL_WRAPPED.match(first_header.strip())
    if wrapped:
        return wrapped.group(2).strip() or f"y{k + 1}"
    bare = re.sub(r"[(\[][^)\]]*[)\]]", " ", first_header)  # units in brackets
    kept = [w for w in re.split(r"[\s_.\-()\[\]|/]+", bare)
            if w and w.lower() not in _KIND_WORDS]
    return " ".join(kept) or f"y{k + 1}"


def _known_quantity(value: str, where: str, source: str) -> str:
    """``value`` if it is a known quantity, else refuse (``where`` says where it was)."""
    problem = quantity_problem(value)
    if problem:
        raise InputError(f"{where}: {problem}", source)
    return value


# --------------------------------------------------------------------------------- NPZ


def read_npz(path: str | os.PathLike[str]) -> FRFData:
    """Read FRFs from a NumPy ``.npz`` archive.

    Parameters
    ----------
    path : str or path-like
        An archive written by :func:`numpy.savez` with the keys ``frequency`` (1-D, Hz) and
        ``frf`` (complex, shape ``(lines, outputs, inputs)``, or ``(lines, outputs)`` for a
        single input), and optionally ``quantity`` (a string: ``"displacement"``,
        ``"velocity"`` or ``"acceleration"``; ``"displacement"`` when absent). Other keys are
        not read; their names are listed in ``attributes["ignored_keys"]``.

    Returns
    -------
    FRFData
        ``source`` is ``str(path)``; ``attributes["quantity_source"]`` says whether the
        quantity was stated or assumed.

    Raises
    ------
    InputError
        One line naming the file, when it is missing, not an ``.npz`` archive (or a damaged
        one), lacks a key, holds a key that is not a ``.npy`` array, a ``frf`` that is real
        or neither 2-D nor 3-D, a ``frequency`` of the wrong length, an unknown ``quantity``,
        pickled objects, arrays of more than :data:`automodal.io.limits.MAX_VALUES` numbers
        (refused from their headers, before they are loaded), or breaks the rules of the FRF
        file.
    """
    return read_refusing(_read_npz, path)


def _read_npz(p: Path, source: str) -> FRFData:
    """:func:`read_npz` (raises :class:`InputError` naming ``source`` on a bad file)."""
    try:
        loaded = np.load(p, allow_pickle=False)
        if not isinstance(loaded, np.lib.npyio.NpzFile):
            raise InputError(f"a single .npy array, not an .npz archive; {NPZ_LAYOUT}",
                             source)
        with loaded as archive:
            keys = list(archive.files)
            arrays = npz_members(archive, NPZ_KEYS, NPZ_LAYOUT, source)
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - zipfile, zlib and numpy raise many kinds
        raise InputError(f"cannot read as an .npz archive: {describe(exc)}", source) from exc
    return npz_frfdata(arrays, keys, source)


def npz_frfdata(arrays: dict[str, np.ndarray], keys: Sequence[str], source: str) -> FRFData:
    """The FRFs of an archive's members ``arrays`` (:data:`NPZ_KEYS` that it has, read by
    :func:`npz_members`); ``keys`` all its members, to name the missing and the ignored."""
    missing = [key for key in ("frequency", "frf") if key not in arrays]
    if missing:
        found = ", ".join(sorted(keys)) or "none"
        raise InputError(f"no key {' or '.join(map(repr, missing))} (keys found: {found}); "
                         f"{NPZ_LAYOUT}", source)
    frequency = np.asarray(arrays["frequency"])
    frf = _npz_frf(arrays["frf"], frequency, source)
    attributes: dict[str, Any] = {"source_format": "NPZ archive"}
    quantity, attributes["quantity_source"] = "displacement", _assumed("NPZ")
    if "quantity" in arrays:
        quantity = _npz_quantity(arrays["quantity"], source)
        attributes["quantity_source"] = "'quantity' key of the NPZ archive"
    ignored = sorted(set(keys) - set(NPZ_KEYS))
    if ignored:
        attributes["ignored_keys"] = ", ".join(ignored)
    if frequency.dtype.kind not in "fiu":
        raise InputError(f"'frequency' must hold real numbers, not dtype {frequency.dtype}",
                         source)
    data = FRFData(frequency=frequency, frf=frf, quantity=quantity, attributes=attributes,
                   source=source)
    check_not_real_valued(data.frf, source)
    return data


NPZ_KEYS = ("frequency", "frf", "quantity")
"""The members of an NPZ archive that are read (others are only named)."""


def npz_members(archive: np.lib.npyio.NpzFile, keys: Sequence[str], layout: str,
                source: str) -> dict[str, np.ndarray]:
    """The members ``keys`` of an open archive (those it has), as arrays.

    Their ``.npy`` headers are checked first: a member that is not an ``.npy`` array is
    refused, and so are members that declare more than
    :data:`~automodal.io.limits.MAX_VALUES` numbers in all, before anything is loaded (a
    small compressed archive may declare or hold a huge array). Other members are not read.
    ``layout`` (what the archive should hold) ends the refusal of a member that is not an
    array.
    """
    names = set(archive.zip.namelist())
    total = 0
    for key in keys:
        member = key if key in names else f"{key}.npy" if f"{key}.npy" in names else None
        if member is None:
            continue
        with archive.zip.open(member) as fp:
            shape = npy_shape(fp)
        if shape is None:
            raise InputError(f"the member {key!r} is not a .npy array; {layout}", source)
        total += math.prod(shape)
    check_size(total, f"the archive ({', '.join(map(repr, keys))})", source)
    return {key: archive[key] for key in keys if key in archive}


def npy_shape(fp: IO[bytes]) -> tuple[int, ...] | None:
    """The shape an ``.npy`` stream declares in its header, None when it is not one."""
    try:
        version = np.lib.format.read_magic(fp)
        if version == (1, 0):
            shape, _, _ = np.lib.format.read_array_header_1_0(fp)
        else:
            shape, _, _ = np.lib.format.read_array_header_2_0(fp)
    except (ValueError, SyntaxError, EOFError, TokenError):  # a damaged header: numpy parses
        return None  # it as a Python literal, so the tokenizer's errors come through too
    return tuple(int(n) for n in shape)


def _npz_frf(frf: np.ndarray, frequency: np.ndarray, source: str) -> np.ndarray:
    """The ``frf`` array as 3-D complex; refuse a real or ambiguous one."""
    if frf.dtype.kind != "c":
        raise InputError(f"'frf' is not complex (dtype {frf.dtype}); real FRFs are refused, "
                         "not given zero phase", source)
    if frf.ndim not in (2, 3):
        raise InputError(f"'frf' has shape {frf.shape}; {NPZ_LAYOUT}", source)
    n_lines = frequency.size if frequency.ndim == 1 else -1
    if frf.shape[0] != n_lines:
        hint = " (transposed? lines must be the first axis)" if n_lines in frf.shape[1:] else ""
        raise InputError(f"'frf' has shape {frf.shape} but 'frequency' has shape "
                         f"{frequency.shape}; the first axis of 'frf' must have one entry per "
                         f"frequency line{hint}", source)
    return frf if frf.ndim == 3 else frf[:, :, np.newaxis]


def _npz_quantity(value: np.ndarray, source: str) -> str:
    """The ``quantity`` entry as a known quantity name."""
    if value.shape != () or value.dtype.kind not in "US":
        raise InputError(f"'quantity' must be one string (one of {', '.join(QUANTITIES)}), not "
                         f"an array of shape {value.shape} and dtype {value.dtype}", source)
    text = value.item()
    if isinstance(text, bytes):
        text = text.decode("utf-8", errors="replace")
    return _known_quantity(str(text), "'quantity'", source)
