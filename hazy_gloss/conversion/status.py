# SPDX-License-Identifier: GPL-3.0-or-later
"""How a texture conversion (convert.py) fails, reports its progress and is cancelled:
:class:`ConversionError` (one line for the user) and its kinds, :class:`Progress` (work done,
ETA, the cancel flag), the text progress bar and :func:`drain`.
"""
from __future__ import annotations

import difflib
import time

__all__ = ("ConversionError", "ConversionOptionError", "did_you_mean", "ConversionCancelled",
           "Progress", "format_seconds", "progress_bar", "drain")


class ConversionError(ValueError):
    """Bad input to a conversion (missing file, mismatched sizes, bad kind...): the message is
    one line meant for the user (several lines given are joined with '; ')."""

    def __init__(self, message=""):
        text = str(message)
        if "\n" in text or "\r" in text:
            text = "; ".join(p.strip() for p in text.splitlines() if p.strip())
        super().__init__(text)


class ConversionOptionError(ConversionError, TypeError):
    """An unknown keyword argument of a conversion (a ConversionError and a TypeError)."""


def did_you_mean(word, choices):
    """' (did you mean 'x'?)' for the closest of ``choices``, or ''."""
    close = difflib.get_close_matches(str(word), list(choices), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


# Progress and cancel
# --------------------------------------------------------------------------------------------


class ConversionCancelled(ConversionError):
    """The conversion was cancelled (Esc in the operator, :meth:`Progress.cancel`); like any
    failure, nothing of it is left in the output folder."""


class Progress:
    """How far a conversion is, and its cancel flag.

    The conversion calls :meth:`begin` with its total work (rows of every tile of every set)
    and :meth:`advance` after each strip; :meth:`advance` raises :class:`ConversionCancelled`
    once :meth:`cancel` was called (between two strips: the run is then undone like a failed
    one).  ``callback(done, total, message)`` is called on every step (the API's
    ``progress=``).  :meth:`status` is the one line the operator and the CLI show: what is
    being done (map or step, UDIM tile, set), percent and time left."""

    def __init__(self, callback=None, clock=None):
        self.callback = callback
        self.clock = clock or time.monotonic
        self.total = 0
        self.done = 0
        self.message = ""
        self.levels = []
        self.cancelled = False
        self.started = self.clock()

    def cancel(self):
        """Ask the running conversion to stop at its next strip (and undo itself)."""
        self.cancelled = True

    def check(self):
        if self.cancelled:
            raise ConversionCancelled("cancelled; the output folder is unchanged")

    def begin(self, total):
        self.total += max(0, int(total))

    def next_item(self, index, count, name, key="set"):
        """Item ``index`` of ``count`` starts: a set of a library batch (``key`` "set") or a
        UDIM tile of a set ("tile"); the fraction is then (items done + this item's fraction)
        / count at each level, and the rows of the item start from 0."""
        keep = [lv for lv in self.levels if lv[0] == "set"] if key != "set" else []
        self.levels = keep + [(key, int(index), max(1, int(count)), str(name))]
        self.total = self.done = 0

    def advance(self, units=0, message=None):
        self.done = min(self.total, self.done + max(0, int(units)))
        if message is not None:
            self.message = message
        if self.callback is not None:
            self.callback(self.done, max(self.total, 1), self.message)
        self.check()

    levels = ()

    @property
    def fraction(self):
        f = self.done / self.total if self.total else 0.0
        for _, i, n, _ in reversed(self.levels):
            f = (i + f) / n
        return min(1.0, f)

    def seconds_left(self):
        """Time left, extrapolated from the rate so far (None before the first strip)."""
        f = self.fraction
        if f <= 0:
            return None
        spent = self.clock() - self.started
        return spent * (1 - f) / f

    def status(self):
        left = self.seconds_left()
        eta = "" if left is None else f", {format_seconds(left)} left"
        parts = [f"{key} {name} ({i + 1} of {n})" for key, i, n, name in self.levels]
        where = f"{', '.join(parts)}: " if parts else ""
        return f"{where}{self.message} {100 * self.fraction:.0f}%{eta}".strip()


def format_seconds(s):
    """'12 s', '3 min 05 s', '2 h 04 min'."""
    s = max(0, int(round(s)))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


def progress_bar(progress, width=30):
    """A text progress bar of a :class:`Progress` (the CLI's): '[#####-----]  50% ...'."""
    n = int(round(width * progress.fraction))
    return f"[{'#' * n}{'-' * (width - n)}] {progress.status()}"


def drain(steps):
    """Run a conversion generator to its end; returns its result (what the blocking API does,
    where the modal operator steps the same generator between events)."""
    while True:
        try:
            next(steps)
        except StopIteration as stop:
            return stop.value
