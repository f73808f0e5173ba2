# SPDX-License-Identifier: GPL-3.0-or-later
"""A text progress bar for the command line (the callbacks the readers call:
progress(fraction, message)).  On a terminal one line redrawn in place; in a log (not a TTY)
a line every 10 %.  Nothing when ``quiet``."""
import sys
import time

__all__ = ("TextProgress",)


class TextProgress:
    """``TextProgress(label)`` is a progress(fraction, message) callable; ``close()`` ends the
    line.  ``stream`` defaults to stderr (stdout stays for the results, e.g. --json)."""

    def __init__(self, label, *, stream=None, quiet=False, width=30):
        self.label = label
        self.stream = sys.stderr if stream is None else stream
        self.quiet = quiet
        self.width = width
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.start = time.perf_counter()
        self.last_step = -1
        self.last_draw = 0.0
        self.drawn = False

    def __call__(self, fraction, message=""):
        if self.quiet:
            return
        f = min(max(float(fraction), 0.0), 1.0)
        if self.tty:
            now = time.perf_counter()
            if now - self.last_draw < 0.1 and f < 1.0:
                return
            self.last_draw = now
            n = int(round(f * self.width))
            bar = "#" * n + "-" * (self.width - n)
            self.stream.write(f"\r{self.label}: [{bar}] {100 * f:5.1f}% {message:<24}")
            self.stream.flush()
            self.drawn = True
            return
        step = int(f * 10)
        if step > self.last_step:
            self.last_step = step
            elapsed = time.perf_counter() - self.start
            self.stream.write(f"{self.label}: {10 * step:3d}% ({message}, {elapsed:.1f} s)\n")
            self.stream.flush()

    def close(self):
        if self.drawn and not self.quiet:
            self.stream.write("\n")
            self.stream.flush()
        self.drawn = False
