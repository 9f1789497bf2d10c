"""A text progress bar with rate and ETA, for long loops over bag messages."""

from __future__ import annotations

import math
import sys
import time
from typing import TextIO

__all__ = ['Progress']


class Progress:
    """
    A progress bar with rate and ETA on a text stream (stderr by default).

    On a terminal the bar is redrawn in place at most every ``interval_s``; otherwise a
    plain line is written every ``log_interval_s`` so that logs stay readable.
    """

    def __init__(self, total: int, *, label: str = '', unit: str = 'msgs',
                 stream: TextIO | None = None, enabled: bool = True,
                 interval_s: float = 0.1, log_interval_s: float = 5.0,
                 width: int = 30) -> None:
        self.total = max(0, int(total))
        self.label = label
        self.unit = unit
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled
        self.tty = bool(getattr(self.stream, 'isatty', lambda: False)())
        self.interval_s = interval_s if self.tty else log_interval_s
        self.width = width
        self.count = 0
        self.start = time.monotonic()
        self._last = self.start          # first draw after one interval: a meaningful rate

    @property
    def rate(self) -> float:
        """Return the items per second so far."""
        elapsed = time.monotonic() - self.start
        return self.count / elapsed if elapsed > 0.0 else 0.0

    def update(self, n: int = 1) -> None:
        """Count ``n`` more items; redraw when due."""
        self.count += n
        now = time.monotonic()
        if self.enabled and now - self._last >= self.interval_s:
            self._last = now
            self._draw(final=False)

    def close(self) -> None:
        """Draw the final state and end the line."""
        if self.enabled:
            self._draw(final=True)

    def text(self) -> str:
        """Return the bar as one line (no carriage return)."""
        total = self.total or 1
        frac = min(1.0, self.count / total)
        filled = int(round(frac * self.width))
        bar = '#' * filled + '.' * (self.width - filled)
        rate = self.rate
        left = (self.total - self.count) / rate if rate > 0 else math.inf
        eta = _clock(left) if math.isfinite(left) else '--:--'
        label = f'{self.label} ' if self.label else ''
        return (f'{label}[{bar}] {100 * frac:5.1f}% {self.count}/{self.total} {self.unit} '
                f'{rate:7.0f} {self.unit}/s  elapsed {_clock(time.monotonic() - self.start)}'
                f'  ETA {eta}')

    def _draw(self, final: bool) -> None:
        if self.tty:
            self.stream.write('\r' + self.text() + ('\n' if final else ''))
        else:
            self.stream.write(self.text() + '\n')
        self.stream.flush()


def _clock(seconds: float) -> str:
    seconds = max(0, int(round(seconds)))
    return f'{seconds // 60:02d}:{seconds % 60:02d}'
