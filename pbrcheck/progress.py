"""Progress display for long work: a bar on a terminal, a few plain lines otherwise (CI logs)."""

from __future__ import annotations

import sys
import time

from .fmt import terminal_safe


class Progress:
    """``with Progress("reference spheres", total=64) as p: p.update(8)``.

    Prints nothing for work that finishes within ``quiet_s`` seconds; on a terminal it redraws one
    line, elsewhere it prints at most one line per ``log_every_s`` seconds.
    """

    def __init__(self, label: str, total: float, unit: str = "", *, quiet_s: float = 2.0,
                 log_every_s: float = 10.0, stream=None, enabled: bool = True):
        # the label names a scene (untrusted): escaped, so no control character reaches the terminal
        self.label, self.total, self.unit = terminal_safe(label), max(float(total), 1e-12), unit
        self.done = 0.0
        self.stream = stream or sys.stderr
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.quiet_s, self.log_every_s = quiet_s, log_every_s
        self.enabled = enabled
        self.t0 = time.perf_counter()
        self._last = 0.0
        self._shown = False

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self._shown and exc[0] is None:
            self._draw(final=True)
        elif self._shown and self.tty:  # an error: erase the bar, so that the error line stands alone
            try:
                self.stream.write("\r\033[K")
                self.stream.flush()
            except (OSError, ValueError):
                pass
        return False

    def update(self, n: float = 1.0, note: str = ""):
        self.done += n
        self.note = note
        now = time.perf_counter()
        if not self.enabled or now - self.t0 < self.quiet_s:
            return
        if self.tty or now - self._last >= self.log_every_s:
            self._draw()
            self._last = now

    def _draw(self, final: bool = False):
        frac = min(self.done / self.total, 1.0)
        el = time.perf_counter() - self.t0
        eta = el / frac - el if frac > 0 else float("nan")
        bar = "#" * int(frac * 30)
        msg = f"{self.label}: [{bar:<30}] {frac * 100:5.1f}%  {el:6.1f}s"
        if not final and frac < 1:
            msg += f"  eta {eta:5.1f}s"
        if self.tty:
            self.stream.write("\r" + msg + ("\n" if final else ""))
        else:
            self.stream.write(msg + "\n")
        self.stream.flush()
        self._shown = True
