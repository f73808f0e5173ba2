# SPDX-License-Identifier: GPL-3.0-or-later
"""Bound the work of one call by counting it, not by timing it.

A fuzz case must not hang.  A wall-clock alarm says so on an idle machine and fails on a loaded
one; a count is the same on every machine.  :class:`Counter` counts the Python work a call does:
every Python function that starts and every backward jump (a loop's next iteration), through
``sys.monitoring`` (Python 3.12+).  Python 3.11 (bpy 4.5) has no ``sys.monitoring``: there the
count is the Python function calls alone (``sys.settrace`` call events), which still bounds any
recursion and any loop that calls Python code.  Over the limit the call is stopped with
:class:`WorkLimit`, raised inside it.

Work in C (a regular expression, zlib, expat) is not counted; the inputs bound it.  ``only``
limits the count to the code under test (its folder): other Python code is not counted and,
on 3.12+, not even seen after its first event, which keeps the cost low.

Used by tests/pure/test_fuzz_mtlx.py, tests/blender/stamp_fuzz.py and
tests/blender/test_convert_safety.py (which load this file by its path).  Wall-clock figures are
benchmarks/time_limits.py's.
"""
from __future__ import annotations

import sys

__all__ = ("WorkLimit", "Counter")


class WorkLimit(Exception):
    """The call did more than its limit of counted operations."""


_MON = getattr(sys, "monitoring", None)


class Counter:
    """Counts operations while it is active (``with Counter() as c:``, the hooks installed once:
    ``sys.monitoring`` re-instruments every code object each time its events change).

    ``c.run(fn, *args, limit=n)``: ``fn(*args)`` with its count in ``c.count``; raises
    :class:`WorkLimit` from inside ``fn`` once the count passes ``limit`` (``None``: count
    only).  ``.unit`` says what is counted."""

    @property
    def unit(self):
        return "Python calls and loop iterations" if self.loops else "Python calls"

    def __init__(self, only=None, loops=True):
        #: folders whose code is counted (None: all Python code); other code's events are
        #: switched off where they fire (sys.monitoring.DISABLE), so it costs nothing after
        self.only = tuple(only) if only else None
        #: count loop iterations too (3.12+); False: calls only, the cheaper bound for code
        #: that is mostly calls (the per-iteration callback is most of the cost)
        self.loops = loops and _MON is not None
        self.count = 0
        self._limit = None
        self._on = False
        self._tool = None
        self._old_trace = None

    def _tick(self):
        if not self._on:
            return
        self.count += 1
        if self._limit is not None and self.count > self._limit:
            self._on = False  # raise once: the handlers the call unwinds through run freely
            raise WorkLimit(f"more than {self._limit} {self.unit}")

    def _start(self, code, offset):
        if self.only is not None and not code.co_filename.startswith(self.only):
            return _MON.DISABLE
        self._tick()

    def _jump(self, code, offset, destination):
        if self.only is not None and not code.co_filename.startswith(self.only):
            return _MON.DISABLE
        if destination <= offset:  # backward: a loop's next iteration
            self._tick()

    def _trace(self, frame, event, arg):  # Python 3.11
        if event == "call" and (self.only is None
                                or frame.f_code.co_filename.startswith(self.only)):
            self._tick()
        return None  # no line events

    def __enter__(self):
        m = _MON
        if m is None:
            self._old_trace = sys.gettrace()
            sys.settrace(self._trace)
            return self
        self._tool = next((t for t in range(6) if m.get_tool(t) is None), None)
        if self._tool is None:
            raise RuntimeError("no free sys.monitoring tool id")
        m.use_tool_id(self._tool, "work_bound")
        m.register_callback(self._tool, m.events.PY_START, self._start)
        m.register_callback(self._tool, m.events.JUMP, self._jump)
        m.set_events(self._tool, m.events.PY_START | (m.events.JUMP if self.loops else 0))
        m.restart_events()  # what an earlier Counter switched off counts again
        return self

    def __exit__(self, *exc):
        m = _MON
        if m is None:
            sys.settrace(self._old_trace)
            return False
        m.set_events(self._tool, 0)
        m.register_callback(self._tool, m.events.PY_START, None)
        m.register_callback(self._tool, m.events.JUMP, None)
        m.free_tool_id(self._tool)
        return False

    def run(self, fn, *args, limit=None, **kwargs):
        self.count, self._limit, self._on = 0, limit, True
        if _MON is None and sys.gettrace() is not self._trace:
            sys.settrace(self._trace)  # an exception in a trace function turns tracing off
        try:
            return fn(*args, **kwargs)
        finally:
            self._on = False
