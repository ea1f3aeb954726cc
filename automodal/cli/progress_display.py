"""The progress line of a command on a terminal: the stage, a bar for a counted stage, and
the time since the run started.

It is drawn on stderr only when stderr is a terminal and the command is not ``--quiet`` (nor
``--json``, for the commands that have it): a report, a pipe or a cron log never sees it. It
redraws one line in place (carriage return, erase to the end of the line), a thread keeps
the time current during a stage that sends nothing for a while (the order scan), and the
line is erased when the run ends, so what the command prints next starts on a clean line.
The events come from :mod:`automodal.progress`; drawing them changes nothing in the run.
"""

from __future__ import annotations

import shutil
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TextIO

from automodal.progress import Progress, ProgressCallback

__all__ = ["ProgressLine", "progress_line", "wanted"]

BAR_WIDTH = 24
"""Characters of the bar of a counted stage."""

TICK_S = 0.25
"""Seconds between redraws of the time while no event comes."""

_ERASE = "\r\x1b[K"  # back to the start of the line, erase to its end


def wanted(quiet: bool, as_json: bool = False, stream: TextIO | None = None) -> bool:
    """Whether to draw progress: on a terminal, neither ``--quiet`` nor ``--json``."""
    stream = sys.stderr if stream is None else stream
    return not (quiet or as_json) and stream.isatty()


class ProgressLine:
    """A :data:`~automodal.progress.ProgressCallback` that draws one line on ``stream``.

    Parameters
    ----------
    stream : text stream
        Where to draw (a terminal).
    tick_s : float or None
        Seconds between redraws of the time while no event comes; ``None``: no thread,
        redraw on events only.
    """

    def __init__(self, stream: TextIO, tick_s: float | None = TICK_S) -> None:
        self._stream = stream
        self._start = time.monotonic()
        self._event: Progress | None = None
        self._shown = False
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = None
        if tick_s is not None:
            self._thread = threading.Thread(target=self._tick, args=(tick_s,), daemon=True)
            self._thread.start()

    def __call__(self, event: Progress) -> None:
        with self._lock:
            self._event = event
            self._draw()

    def text(self, event: Progress, elapsed_s: float) -> str:
        """The line for ``event`` after ``elapsed_s`` seconds (without control codes)."""
        if event.total:
            filled = BAR_WIDTH * event.done // event.total
            what = (f"{event.label} [{'#' * filled}{'.' * (BAR_WIDTH - filled)}]"
                    f" {event.done}/{event.total}")
        else:
            what = f"{event.label} ..."
        return f"{what}  {elapsed_s:.1f} s"

    def close(self) -> None:
        """Stop the thread and erase the line."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        with self._lock:
            if self._shown:
                self._stream.write(_ERASE)
                self._stream.flush()
                self._shown = False

    def _draw(self) -> None:
        if self._event is None or self._stop.is_set():
            return
        columns = shutil.get_terminal_size((80, 24)).columns
        line = self.text(self._event, time.monotonic() - self._start)[: max(columns - 1, 10)]
        self._stream.write(_ERASE + line)
        self._stream.flush()
        self._shown = True

    def _tick(self, tick_s: float) -> None:
        while not self._stop.wait(tick_s):
            with self._lock:
                self._draw()


@contextmanager
def progress_line(enabled: bool, stream: TextIO | None = None,
                  tick_s: float | None = TICK_S) -> Iterator[ProgressCallback | None]:
    """A :class:`ProgressLine` on ``stream`` (default stderr) while the block runs, erased
    at its end (also when it raises); ``None`` when not ``enabled``."""
    if not enabled:
        yield None
        return
    line = ProgressLine(sys.stderr if stream is None else stream, tick_s)
    try:
        yield line
    finally:
        line.close()
