# SPDX-License-Identifier: GPL-3.0-or-later
"""Every test can fail, and fails the same on any machine: a scan of tests/ (AST, no import).

- no assert on wall-clock time: an assert whose expression calls a clock (time.perf_counter,
  time.time, monotonic, process_time, thread_time), reads a name computed from one, or names
  seconds / elapsed / slowest / runtime / duration (a helper's timing); no ``signal.setitimer``
  or ``signal.alarm`` (a per-case alarm is a wall-clock limit).  Where a test must bound work it
  counts operations (tests/pure/work_bound.py) or injects a clock; time limits are
  benchmarks/time_limits.py's;
- no skip on a path outside the repository or on an environment variable: a ``pytest.skip``
  under a condition, or a ``skipif``, that reads ``os.environ`` / ``os.getenv``, an absolute
  path or the home folder (directly or through a name computed from one).

Subprocess timeouts stay: they end a child that hangs, they are not a check.
"""
import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TESTS = ROOT / "tests"
#: the image codecs' tests and fuzzers, rewritten elsewhere with their own wall-clock bounds
#: (they keep them until that rewrite lands)
NOT_YET = {"tests/pure/test_imagecheck_formats.py", "tests/pure/test_fuzz_readers.py",
           "tests/pure/fuzz_files.py", "tests/pure/test_imagestream.py",
           "tests/blender/test_imagecheck.py", "tests/blender/test_composite.py"}
CLOCKS = {"perf_counter", "perf_counter_ns", "time", "time_ns", "monotonic", "monotonic_ns",
          "process_time", "process_time_ns", "thread_time", "thread_time_ns"}
TIMING_WORDS = re.compile(r"(seconds|elapsed|slowest|runtime|duration|per_pair)", re.I)


def _files():
    return sorted(p for p in TESTS.rglob("*.py")
                  if p.relative_to(ROOT).as_posix() not in NOT_YET)


def _is_clock(node):
    """time.<clock>(), or a clock imported by its name (``from time import perf_counter``)."""
    if not isinstance(node, ast.Call):
        return False
    f = node.func
    if isinstance(f, ast.Attribute):
        return f.attr in CLOCKS and isinstance(f.value, ast.Name) and f.value.id == "time"
    return isinstance(f, ast.Name) and f.id in CLOCKS - {"time", "time_ns"}


def _is_outside(node):
    """os.environ / os.getenv, an absolute path literal, the home folder."""
    if isinstance(node, ast.Attribute) and node.attr in ("environ", "getenv", "home",
                                                         "expanduser"):
        return True
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value.startswith(("/", "~")) and len(node.value) > 1
    return False


_FUNCS = (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)


def _scopes(tree):
    """(scope, its own nodes) for the module and every function: a name is followed within
    the scope that assigns it (nested functions are scopes of their own)."""
    out = []
    for scope in [tree] + [n for n in ast.walk(tree) if isinstance(n, _FUNCS)]:
        own, todo = [], list(ast.iter_child_nodes(scope))
        while todo:
            n = todo.pop()
            own.append(n)
            if not isinstance(n, _FUNCS):
                todo.extend(ast.iter_child_nodes(n))
        out.append((scope, own))
    return out


def _tainted(own, test):
    """Names assigned in the nodes ``own`` from an expression with a node ``test`` accepts or
    with a name already tainted, to a fixed point."""
    names = set()
    assigns = [n for n in own if isinstance(n, (ast.Assign, ast.AugAssign, ast.AnnAssign))]
    while True:
        before = len(names)
        for a in assigns:
            if a.value is None:
                continue
            if any(test(x) or (isinstance(x, ast.Name) and x.id in names)
                   for x in ast.walk(a.value)):
                targets = a.targets if isinstance(a, ast.Assign) else [a.target]
                for t in targets:
                    names |= {x.id for x in ast.walk(t) if isinstance(x, ast.Name)}
        if len(names) == before:
            return names


def _reads(expr, test, names):
    return any(test(x) or (isinstance(x, ast.Name) and x.id in names) for x in ast.walk(expr))


def _timing_word(expr):
    """A name, attribute or subscript key that says it holds a time."""
    return any((isinstance(x, ast.Name) and TIMING_WORDS.search(x.id))
               or (isinstance(x, ast.Attribute) and TIMING_WORDS.search(x.attr))
               or (isinstance(x, ast.Subscript) and isinstance(x.slice, ast.Constant)
                   and isinstance(x.slice.value, str) and TIMING_WORDS.search(x.slice.value))
               for x in ast.walk(expr))


def wall_clock_problems(source, name="<test>"):
    tree = ast.parse(source)
    out = set()
    for _, own in _scopes(tree):
        timed = _tainted(own, _is_clock)
        for node in own:
            if isinstance(node, ast.Assert) and (_reads(node.test, _is_clock, timed)
                                                 or _timing_word(node.test)):
                out.add(f"{name}:{node.lineno}: assert on wall-clock time")
    for node in ast.walk(tree):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                and node.func.attr in ("setitimer", "alarm")
                and isinstance(node.func.value, ast.Name) and node.func.value.id == "signal"):
            out.add(f"{name}:{node.lineno}: a wall-clock alarm (signal.{node.func.attr})")
    return sorted(out)


def _is_skip(call):
    return (isinstance(call, ast.Call) and isinstance(call.func, ast.Attribute)
            and call.func.attr in ("skip", "skipif")
            and isinstance(call.func.value, (ast.Name, ast.Attribute)))


def outside_skip_problems(source, name="<test>"):
    tree = ast.parse(source)
    out = set()
    scopes = _scopes(tree)
    module = _tainted(scopes[0][1], _is_outside)  # module constants reach every function
    for _, own in scopes:
        outside = _tainted(own, _is_outside) | module
        for node in own:
            if isinstance(node, ast.If) and any(_is_skip(x) for b in node.body
                                                for x in ast.walk(b)):
                if _reads(node.test, _is_outside, outside):
                    out.add(f"{name}:{node.lineno}: skips on a path outside the repository "
                            f"or an environment variable")
            if (_is_skip(node) and node.func.attr == "skipif" and node.args
                    and _reads(node.args[0], _is_outside, outside)):
                out.add(f"{name}:{node.lineno}: skipif on a path outside the repository or "
                        f"an environment variable")
    return sorted(out)


def test_no_test_asserts_on_wall_clock_time():
    problems = []
    for p in _files():
        problems += wall_clock_problems(p.read_text(), p.relative_to(ROOT).as_posix())
    assert not problems, "\n".join(problems)


def test_no_test_skips_on_outside_paths_or_environment():
    problems = []
    for p in _files():
        problems += outside_skip_problems(p.read_text(), p.relative_to(ROOT).as_posix())
    assert not problems, "\n".join(problems)


# the scan itself: what it must catch and what it must let through

@pytest.mark.parametrize("src", [
    "import time\nt = time.perf_counter()\nf()\nassert time.perf_counter() - t < 1.0\n",
    "import time\nt0 = time.time()\ndt = time.time() - t0\nper = dt / 5\nassert per < 0.25\n",
    "assert fuzz.slowest[0] < 5.0\n",
    "assert out['seconds'] < 60\n",
    "import signal\nsignal.setitimer(signal.ITIMER_REAL, 5.0)\n",
    "from time import monotonic\ndef test():\n    t = monotonic()\n    f()\n"
    "    assert monotonic() - t < 2\n",
])
def test_the_scan_finds_wall_clock_asserts(src):
    assert wall_clock_problems(src)


@pytest.mark.parametrize("src", [
    "import time\nold = time.time() - 3600\nos.utime(p, (old, old))\nassert p.exists()\n",
    "import subprocess\nr = subprocess.run(['x'], timeout=120)\nassert r.returncode == 0\n",
    "assert counts['hang'] == 0\n",
])
def test_the_scan_lets_other_code_through(src):
    assert not wall_clock_problems(src)


@pytest.mark.parametrize("src", [
    "from pathlib import Path\nex = Path('/work/research/x')\nif not ex.is_dir():\n"
    "    pytest.skip('not here')\n",
    "import os\n@pytest.mark.skipif(os.environ.get('X', '') == '', reason='set X')\n"
    "def test_x(): pass\n",
    "import os\nif not os.getenv('X'):\n    pytest.skip('set X')\n",
    "from pathlib import Path\nif not (Path.home() / 'data').exists():\n    pytest.skip('no')\n",
])
def test_the_scan_finds_outside_skips(src):
    assert outside_skip_problems(src)


@pytest.mark.parametrize("src", [
    "import bpy\n@pytest.mark.skipif(bpy.app.version < (5, 0, 0), reason='5.0+')\n"
    "def test_x(): pass\n",
    "if version < (5, 0):\n    pytest.skip('no table before 5.0')\n",
])
def test_the_scan_lets_version_skips_through(src):
    assert not outside_skip_problems(src)
