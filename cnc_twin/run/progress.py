"""A one-line terminal progress bar on stderr, drawn only when stderr is a terminal."""

from __future__ import annotations

import sys
import time
from typing import TextIO


class ProgressBar:
    """Callable as ``bar(done, total)``; redraws at most every ``min_interval`` seconds.

    Parameters
    ----------
    label
        text in front of the bar.
    period
        simulated seconds per unit of ``done`` (shows simulated time).
    stream
        where to draw; defaults to stderr. Nothing is drawn unless it is a TTY.
    start_line
        printed (one line) at the first call when ``stream`` is not a TTY, instead of
        the bar: the run has begun (a log, a pipe).
    """

    def __init__(self, label: str, *, period: float, stream: TextIO | None = None, min_interval: float = 0.1,
                 start_line: str | None = None):
        self.label = label
        self.start_line = start_line
        self.period = period
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = bool(getattr(self.stream, "isatty", lambda: False)())
        self.min_interval = min_interval
        self._last = 0.0
        self._drawn = False

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            if self.start_line is not None:
                self.stream.write(self.start_line + "\n")
                self.stream.flush()
                self.start_line = None
            return
        now = time.monotonic()
        if done < total and now - self._last < self.min_interval:
            return
        self._last = now
        width = 30
        frac = done / total if total else 1.0
        filled = int(round(frac * width))
        bar = "#" * filled + "-" * (width - filled)
        self.stream.write(
            f"\r{self.label} [{bar}] {frac * 100:5.1f}%  {done * self.period:7.2f} / {total * self.period:.2f} s sim"
        )
        self._drawn = True
        if done >= total:
            self.stream.write("\n")
        self.stream.flush()
