"""``automodal design``: the frequency lines to measure, from a band and the expected modes.

Gathers the expected modes (``--mode F:ZETA`` values and/or a file read by
:func:`automodal.io.line_design_files.read_expected_modes`), designs the lines with
:func:`automodal.core.line_design.design_lines` and writes them. Every problem is an
:class:`~automodal.errors.InputError` raised before anything is written.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence

import numpy as np

from automodal.core.line_design import LineDesign, design_lines
from automodal.errors import InputError


def parse_mode(text: str) -> tuple[float, float]:
    """``"12.5:0.01"`` (frequency in Hz, damping ratio) as numbers.

    Raises
    ------
    InputError
        Not two numbers separated by a colon.
    """
    freq, sep, zeta = str(text).partition(":")
    try:
        if not sep:
            raise ValueError
        f, z = float(freq), float(zeta)
    except ValueError:
        raise InputError(f"--mode {text!r}: give FREQUENCY_HZ:DAMPING_RATIO, e.g."
                         " 12.5:0.01") from None
    if not (math.isfinite(f) and f > 0 and math.isfinite(z) and 0 < z < 1):
        raise InputError(f"--mode {text!r}: the frequency must be positive and the damping"
                         " ratio strictly between 0 and 1 (a ratio: 1 % is 0.01)")
    return f, z


def expected_modes(
    modes: Sequence[str], modes_file: str | os.PathLike[str] | None
) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies and damping ratios from ``--mode`` values and a modes file together.

    Raises
    ------
    InputError
        No mode given, a bad ``--mode``, or a file that cannot be read.
    """
    pairs = [parse_mode(m) for m in modes]
    f = np.array([p[0] for p in pairs], dtype=float)
    z = np.array([p[1] for p in pairs], dtype=float)
    if modes_file is not None:
        from automodal.io.line_design_files import read_expected_modes

        ff, zz = read_expected_modes(modes_file)
        f, z = np.concatenate([f, ff]), np.concatenate([z, zz])
    if f.size == 0:
        raise InputError("no expected mode: give --mode F:ZETA (repeated) or --modes FILE")
    return f, z


def design(
    band_hz: tuple[float, float],
    n_lines: int,
    modes: Sequence[str],
    modes_file: str | os.PathLike[str] | None = None,
    rule: str = "modal",
    frequency_uncertainty: float = 0.0,
) -> tuple[LineDesign, int]:
    """The lines for the modes of ``--mode`` values and a modes file (:func:`expected_modes`),
    by :func:`~automodal.core.line_design.design_lines`, and how many of the given modes it
    left out (outside the band).

    Raises
    ------
    InputError
        Everything :func:`expected_modes` and ``design_lines`` refuse.
    """
    f, z = expected_modes(modes, modes_file)
    try:
        made = design_lines(band_hz, n_lines, f, z, rule=rule,
                            frequency_uncertainty=frequency_uncertainty)
    except ValueError as exc:
        raise InputError(str(exc)) from None
    return made, int(f.size - made.mode_frequency_hz.size)
