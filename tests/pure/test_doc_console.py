# SPDX-License-Identifier: GPL-3.0-or-later
"""The docs' Python blocks paste into Blender's Python console (docs that run).

Blender's console (``console_python.execute``) pushes a pasted text line by line into a
``code.InteractiveConsole``, a blank line as ``"\\n"``: a compound statement (``if``, ``for``)
ends only at a blank line, and a statement right after its indented block is a SyntaxError
there although the block runs as a script.  tests/blender/test_docs.py runs every block as a
script; this checks, without bpy, that pasted line by line each block compiles and runs every
statement it has, once."""
import ast
import code
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
_BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


def blocks():
    out = []
    for path in DOCS:
        text = path.read_text(encoding="utf-8")
        for m in _BLOCK.finditer(text):
            out.append((path.name, text[:m.start()].count("\n") + 2, m.group(1)))
    return out


def paste(block):
    """(syntax errors, statements run) of ``block`` pushed line by line as Blender's console
    does; nothing is executed."""
    errors, run = [], []

    class Console(code.InteractiveConsole):
        def runcode(self, _code):
            run.append(len(ast.parse("\n".join(self.buffer).strip()).body))

        def showsyntaxerror(self, filename=None, **_kw):
            errors.append("\n".join(self.buffer))

    console = Console()
    more = False
    for line in block.splitlines():
        more = console.push(line if line.strip() else "\n")
    if more:
        console.push("\n")
    return errors, sum(run)


def test_the_check_sees_a_block_that_does_not_paste():
    bad = "import math\nif math.pi > 3:\n    x = 1\ny = 2\n"
    errors, _ = paste(bad)
    assert errors
    errors, run = paste(bad.replace("    x = 1\n", "    x = 1\n\n"))
    assert not errors and run == 3


BLOCKS = blocks()


@pytest.mark.parametrize("doc,line,block", BLOCKS, ids=[f"{d}:{n}" for d, n, _ in BLOCKS])
def test_block_pastes_into_the_console(doc, line, block):
    errors, run = paste(block)
    assert not errors, f"{doc} line {line}: a statement follows an indented block without a " \
                       f"blank line (SyntaxError in Blender's console): {errors[0]!r}"
    assert run == len(ast.parse(block).body), f"{doc} line {line}: not every statement ran"
