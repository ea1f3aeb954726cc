"""Where a run is, for a progress display: a small typed event and the helpers that send it.

:func:`automodal.identify` (and the application's ``run_file`` and ``calibrate_data``) take
``progress``, a callable that receives a :class:`Progress` when a stage starts and as the
counted work of a stage (the bootstrap replicates) finishes. The events only describe the
run: they never change what it computes, and are sent in the same order whatever
``jobs`` (always from the calling thread). ``None`` sends nothing.

A stage of a nested run carries a ``part``: the output-only first pass of time records
(``"first pass"``), one sub-band of a split band (``"sub-band 2 of 3"``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

__all__ = ["STAGES", "Progress", "ProgressCallback", "counter", "tell", "within"]

STAGES = (
    "reading",  # the input file
    "spectra",  # time records to FRFs or half spectra
    "checks",  # the band, the data checks and the noise model
    "orders",  # the order scan
    "reference",  # the reference model
    "bootstrap",  # the bootstrap replicates (counted)
    "summary",  # clustering, physicalness and statistics
    "refinement",  # maximum-likelihood refinement of the physical modes
    "calibration",  # the bootstrap of an FE model calibration (counted)
    "writing",  # the reports
)
"""The stages, in the order a run goes through them (a run skips those it does not need)."""


@dataclass(frozen=True)
class Progress:
    """One progress event.

    Attributes
    ----------
    stage : str
        One of :data:`STAGES`.
    done : int
        Units of the stage finished (bootstrap replicates); 0 when a stage starts.
    total : int or None
        Units of the stage in all, ``None`` for a stage that is not counted.
    part : str
        The nested run the stage belongs to (``"first pass"``, ``"sub-band 1 of 2"``;
        nested parts joined by ``", "``), ``""`` for the run itself.
    """

    stage: str
    done: int = 0
    total: int | None = None
    part: str = ""

    def __post_init__(self) -> None:
        if self.stage not in STAGES:
            raise ValueError(f"unknown stage {self.stage!r} (one of {', '.join(STAGES)})")
        if self.done < 0 or (self.total is not None and not 0 <= self.done <= self.total):
            raise ValueError(f"done {self.done} of total {self.total} is not a count")

    @property
    def label(self) -> str:
        """``"part: stage"``, or the stage alone."""
        return f"{self.part}: {self.stage}" if self.part else self.stage


ProgressCallback = Callable[[Progress], None]


def tell(progress: ProgressCallback | None, stage: str) -> None:
    """Send the start of an uncounted ``stage`` (nothing when ``progress`` is ``None``)."""
    if progress is not None:
        progress(Progress(stage))


def counter(
    progress: ProgressCallback | None, stage: str, total: int
) -> Callable[[int], None] | None:
    """Start a counted ``stage`` of ``total`` units and return the callback the numerical
    core calls with the units finished since its last call (``None`` for ``None``)."""
    if progress is None:
        return None
    progress(Progress(stage, 0, total))
    state = {"done": 0}

    def finished(n: int) -> None:
        state["done"] = min(total, state["done"] + int(n))
        progress(Progress(stage, state["done"], total))

    return finished


def within(progress: ProgressCallback | None, part: str) -> ProgressCallback | None:
    """The callback of a nested run: its events carry ``part`` (after the caller's own)."""
    if progress is None:
        return None

    def relabelled(event: Progress) -> None:
        progress(replace(event, part=f"{part}, {event.part}" if event.part else part))

    return relabelled
