# SPDX-License-Identifier: GPL-3.0-or-later
"""Pure (no bpy) test suite configuration.

* Puts the repository root (two levels up) and this directory on sys.path, so the tests import
  ``hazy_gloss`` from the checkout and the helpers ``reference`` / ``hg_support`` directly
  (there is deliberately no tests/__init__.py).
* Hypothesis profile "pure" (default): derandomized (the same examples every run, so the suite
  is reproducible in CI) and no example database.  ``HYPOTHESIS_PROFILE=explore`` draws fresh
  random examples, ``HG_EXAMPLES_SCALE=10`` multiplies the example counts (local bug hunting).
* At the end of the run, prints the worst errors against the mpmath reference seen by the tests.
"""
import os
import sys
from pathlib import Path

_HERE = Path(__file__).resolve().parent
_ROOT = _HERE.parents[1]
for _p in (str(_ROOT), str(_HERE)):
    if _p not in sys.path:
        sys.path.insert(0, _p)

from hypothesis import settings  # noqa: E402

settings.register_profile("pure", derandomize=True, database=None, deadline=None,
                          print_blob=True)
settings.register_profile("explore", derandomize=False, database=None, deadline=None,
                          print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "pure"))


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    try:
        import hg_support
    except ImportError:  # pragma: no cover
        return
    lines = hg_support.WORST.lines()
    if not lines:
        return
    terminalreporter.section("hazy_gloss: worst errors against the mpmath reference")
    terminalreporter.write_line(
        "  float64: relative error ('/cond': divided by the condition number of the quantity; "
        "'@r': reference Gulbrandsen at the code's rounded r, informative only).  "
        "float32: absolute error.")
    for line in lines:
        terminalreporter.write_line(line)
