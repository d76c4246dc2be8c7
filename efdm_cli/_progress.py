"""A progress line for long runs: redrawn in place on a TTY, plain lines otherwise."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TextIO

__all__ = ["Progress"]


class Progress:
    """Report ``frame i/total, fps`` on ``stream`` while frames are processed.

    On a TTY the line is redrawn in place (at most every ``interval``
    seconds), starting once the run has lasted ``delay`` seconds, so short
    runs print nothing.  Otherwise (a log file, a pipe) a plain line is
    written at every 5 % of ``total`` when ``total >= min_frames``, or every
    ``every`` frames when the total is unknown.

    Parameters
    ----------
    total : int or None
        Expected number of frames, if known.
    stream : TextIO
        Usually ``sys.stderr``.
    enabled : bool
        ``False`` silences everything (``--quiet``).
    label : str
        Prefix of each line.
    clock : callable
        Seconds, monotonic (injectable for tests).
    """

    def __init__(
        self,
        total: int | None,
        stream: TextIO,
        *,
        enabled: bool = True,
        label: str = "efdm track",
        clock: Callable[[], float] = time.perf_counter,
        delay: float = 0.5,
        interval: float = 0.1,
        min_frames: int = 100,
        every: int = 250,
    ) -> None:
        self.total, self.stream, self.label, self.clock = total, stream, label, clock
        self.delay, self.interval, self.every = delay, interval, every
        self.tty = enabled and stream.isatty()
        self.plain = enabled and not self.tty and (total is None or total >= min_frames)
        self._start = clock()
        self._last_draw = -float("inf")
        self._width = 0  # length of the line on screen (TTY)
        self._step = 0  # last 5 % step printed (plain)
        self._done = 0
        self._drawn = -1  # frame count on screen (TTY)

    @property
    def shown(self) -> bool:
        """Whether this run reports its progress (a TTY, or a long run to a log)."""
        return self.tty or self.plain

    def text(self, done: int) -> str:
        """``label: frame done/total (p %), f fps, ETA t`` (no total: no percentage or ETA)."""
        elapsed = self.clock() - self._start
        fps = done / elapsed if elapsed > 0 else 0.0
        if self.total:
            pct = min(100, 100 * done // self.total)
            line = f"{self.label}: frame {done}/{self.total} ({pct} %), {fps:.1f} fps"
            if 0 < done < self.total and fps > 0:
                line += f", ETA {_duration((self.total - done) / fps)}"
            return line
        return f"{self.label}: frame {done}, {fps:.1f} fps"

    def update(self, done: int) -> None:
        """Record that ``done`` frames are finished; print if it is time to."""
        self._done = done
        if self.tty:
            now = self.clock()
            if now - self._start >= self.delay and now - self._last_draw >= self.interval:
                self._draw(done)
                self._last_draw = now
        elif self.plain:
            if self.total:
                step = 20 * done // self.total
                if step > self._step:
                    self._step = step
                    self._line(self.text(done))
            elif done % self.every == 0:
                self._line(self.text(done))

    def close(self) -> None:
        """Finish the line on a TTY (if one was drawn)."""
        if self.tty and self._width:
            if self._drawn != self._done:
                self._draw(self._done)
            self._write("\n")
            self._width = 0

    def _draw(self, done: int) -> None:
        line = self.text(done)
        self._write("\r" + line.ljust(self._width))
        self._width, self._drawn = len(line), done

    def _line(self, line: str) -> None:
        self._write(line + "\n")

    def _write(self, text: str) -> None:
        """Write and flush; a closed or broken stream silences the progress, not the run."""
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):
            self.tty = self.plain = False
            self._width = 0


def _duration(seconds: float) -> str:
    """``42 s``, ``3 min 05 s`` or ``1 h 02 min``."""
    whole = round(seconds)
    if whole < 60:
        return f"{whole} s"
    minutes, secs = divmod(whole, 60)
    if minutes < 60:
        return f"{minutes} min {secs:02d} s"
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes:02d} min"
