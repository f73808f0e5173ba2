# SPDX-License-Identifier: GPL-3.0-or-later
"""A document the code names is in the repository: every ``*.md`` a module, script, benchmark
or test cites is at the repository's top, under docs/ or tests/, or is a benchmark's own report
(out/report/<benchmark>.md, written by benchmarks/<benchmark>.py).  The rule is also run on
made-up text, so that it can fail."""
import pathlib
import re

ROOT = pathlib.Path(__file__).resolve().parents[2]
CITED = re.compile(r"[A-Za-z0-9_./-]+\.md\b")


def missing(text):
    """The ``*.md`` names ``text`` cites that the repository does not hold."""
    out = []
    for name in CITED.findall(text):
        name = name.removeprefix("./")
        candidates = [ROOT / name, ROOT / "docs" / name, ROOT / "tests" / name]
        report = ROOT / "benchmarks" / (pathlib.Path(name).stem + ".py")
        if not any(c.is_file() for c in candidates) and not report.is_file():
            out.append(name)
    return out


def test_the_rule_can_fail():
    assert missing("see docs/mapping.md and README.md") == []
    assert missing("(BLENDER-FACTS.md, svm/closure.h)") == ["BLENDER-FACTS.md"]
    assert missing("docs/no-such-page.md") == ["docs/no-such-page.md"]


def test_every_cited_document_exists():
    bad = {}
    for folder in ("hazy_gloss", "scripts", "benchmarks", "tests"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            if path == pathlib.Path(__file__).resolve():
                continue
            gone = missing(path.read_text(encoding="utf-8"))
            if gone:
                bad[str(path.relative_to(ROOT))] = gone
    assert not bad, bad
