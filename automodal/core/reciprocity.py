"""Maxwell-Betti reciprocity: identify a many-inputs test as a many-outputs one."""

from __future__ import annotations

import numpy as np


def apply_reciprocity(H: np.ndarray, warnings: list[str]) -> tuple[np.ndarray, bool]:
    """Swap inputs and outputs (``H^T``) when there are more inputs than outputs.

    A roving-hammer test (one sensor, many hit points) is, by Maxwell-Betti reciprocity, the
    same as one force and many sensors. Identification is much cheaper and better posed
    with many outputs (the block rows scale with ``n / ny``), and the mode shapes then live
    on the hit points, which is what such a test measures.

    Parameters
    ----------
    H : ndarray, shape (N, ny, nu)
        FRF.
    warnings : list of str
        Receives a warning when the roles are swapped.

    Returns
    -------
    H : ndarray
        ``H`` or its per-line transpose (contiguous).
    swapped : bool
        Whether inputs and outputs were swapped.
    """
    if H.shape[2] <= H.shape[1]:
        return H, False
    warnings.append(
        f"reciprocity assumed: the {H.shape[2]} inputs were treated as outputs and the"
        f" {H.shape[1]} output(s) as input(s); mode shapes are given over the inputs"
    )
    return np.ascontiguousarray(H.transpose(0, 2, 1)), True
