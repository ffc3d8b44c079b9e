"""The command line's progress bar: `ProgressBar(label)` is a `progress(done, total)` drawn by tqdm.

It draws on stderr only when stderr is a terminal; otherwise (pipes, files, CI logs, tests) every
call is a no-op, so output stays clean. It shows a bar, the percentage, the pellet counts, the rate
in pellets/s and the time left (ETA), and ends its line when done reaches total (or on `close()`).

The rate counts only this session's pellets over this session's time: the bar starts at the first
report it receives (after the first chunk, which in a resumed run follows the rows already done),
and tqdm's `initial` keeps the rows before it out of the rate, so `--resume` shows the true rate.
"""

from __future__ import annotations

import sys

from tqdm import tqdm

__all__ = ["ProgressBar"]


class _Bar(tqdm):
    monitor_interval = 0  # no monitor thread: the bar is drawn from the run's own thread only


class ProgressBar:
    """Callable as progress(done, total) with pellet counts; use `close()` (or `with`) to end the line."""

    INTERVAL = 0.1  # s between redraws (the last one is always drawn)

    def __init__(self, label: str, stream=None, *, enabled: bool | None = None):
        self.label = label
        self.stream = sys.stderr if stream is None else stream
        if enabled is None:
            try:
                enabled = bool(self.stream.isatty())
            except (AttributeError, ValueError, OSError):
                enabled = False
        self.enabled = enabled
        self._bar = None

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            return
        try:
            if self._bar is None or self._bar.total != total:
                self.close()
                self._bar = _Bar(
                    total=total,
                    initial=done,
                    desc=self.label,
                    unit=" pellets",
                    unit_scale=True,
                    file=self.stream,
                    mininterval=self.INTERVAL,
                    smoothing=0,
                    dynamic_ncols=True,
                    leave=True,
                )
            elif done > self._bar.n:
                self._bar.update(done - self._bar.n)
            if total > 0 and done >= total:
                self.close()
        except (OSError, ValueError):  # a closed or broken terminal must not stop the run
            self.enabled = False

    def close(self) -> None:
        """End the line if one is drawn (idempotent)."""
        bar, self._bar = self._bar, None
        if bar is not None:
            try:
                bar.close()
            except (OSError, ValueError):
                pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False
