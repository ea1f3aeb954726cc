"""The response quantities an FRF can be given in (no numpy: the command line's option
choices are built from them without loading the numerical stack)."""

from __future__ import annotations

__all__ = ["QUANTITIES", "quantity_power"]

QUANTITIES = ("displacement", "velocity", "acceleration")
"""Response quantities an FRF can be given in: receptance, mobility, accelerance."""


def quantity_power(quantity: str) -> int:
    """The power ``p`` of ``(j w)^p`` that turns a receptance into ``quantity``.

    Raises
    ------
    ValueError
        If ``quantity`` is not one of :data:`QUANTITIES`.
    """
    if quantity not in QUANTITIES:
        raise ValueError(f"quantity must be one of {QUANTITIES}, got {quantity!r}")
    return QUANTITIES.index(quantity)
