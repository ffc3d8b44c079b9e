"""A dependency-free progress bar for the command line: `ProgressBar(label)` is a `progress(done, total)`.

It draws carriage-return updates on stderr only when stderr is a terminal; otherwise (pipes, files,
CI logs, tests) every call is a no-op, so output stays clean. It shows a bar, the percentage, the
pellet counts and the rate in pellets/s, and ends its line when done reaches total (or on `close()`).
"""

from __future__ import annotations

import sys
import time

__all__ = ["ProgressBar"]


class ProgressBar:
    """Callable as progress(done, total) with pellet counts; use `close()` (or `with`) to end the line."""

    WIDTH = 24  # characters of the bar
    INTERVAL = 0.1  # s between redraws (the last one is always drawn)

    def __init__(self, label: str, stream=None, *, enabled: bool | None = None, clock=time.monotonic):
        self.label = label
        self.stream = sys.stderr if stream is None else stream
        if enabled is None:
            try:
                enabled = bool(self.stream.isatty())
            except (AttributeError, ValueError, OSError):
                enabled = False
        self.enabled = enabled
        self._clock = clock
        self._start = clock()
        self._last_draw = None
        self._open = False  # a line is drawn and not yet ended
        self._width = 0  # length of the last line drawn, to blank leftovers

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            return
        now = self._clock()
        finished = total > 0 and done >= total
        if not finished and self._last_draw is not None and now - self._last_draw < self.INTERVAL:
            return
        self._last_draw = now
        self._draw(self.render(done, total, now - self._start))
        if finished:
            self.close()

    def render(self, done: int, total: int, elapsed: float) -> str:
        """The text of one update (without the carriage return)."""
        fraction = min(max(done / total, 0.0), 1.0) if total > 0 else 0.0
        filled = int(round(fraction * self.WIDTH))
        bar = "#" * filled + "." * (self.WIDTH - filled)
        rate = done / elapsed if elapsed > 0 else 0.0
        return f"{self.label} [{bar}] {100 * fraction:5.1f}%  {done:,}/{total:,} pellets  {_rate(rate)} pellets/s"

    def _draw(self, text: str) -> None:
        pad = " " * max(self._width - len(text), 0)
        try:
            self.stream.write("\r" + text + pad)
            self.stream.flush()
        except (OSError, ValueError):  # a closed or broken terminal must not stop the run
            self.enabled = False
            return
        self._width = len(text)
        self._open = True

    def close(self) -> None:
        """End the line if one is drawn (idempotent)."""
        if self._open:
            self._open = False
            try:
                self.stream.write("\n")
                self.stream.flush()
            except (OSError, ValueError):
                pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


def _rate(x: float) -> str:
    """Pellets per second, short: 950, 12.3k, 4.56M, 1.23G."""
    for scale, suffix in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if x >= scale:
            return f"{x / scale:.3g}{suffix}"
    return f"{x:.0f}"
