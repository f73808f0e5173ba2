# SPDX-License-Identifier: GPL-3.0-or-later
"""The generated parts of the docs are up to date: docs/architecture.md's import diagram is what
scripts/architecture.py draws from the code now, docs/parameters.md's tables what
scripts/parameter_table.py writes from the parameter schema (their ``--check``)."""
import importlib
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "architecture.py"
TABLES = ROOT / "scripts" / "parameter_table.py"


def _check(script):
    """The script's ``--check`` run as a user would: its stderr."""
    run = subprocess.run([sys.executable, str(script), "--check"], capture_output=True,
                         text=True, cwd=ROOT, timeout=120)
    assert run.returncode == 0, run.stderr.strip() or run.stdout.strip()
    return run.stderr


def _script(name):
    """Import scripts/<name>.py as a module."""
    sys.path.insert(0, str(SCRIPT.parent))
    try:
        return importlib.import_module(name)
    finally:
        sys.path.remove(str(SCRIPT.parent))


def test_architecture_diagram_is_current():
    stderr = _check(SCRIPT)
    assert "outside the layers' folders" not in stderr, stderr.strip()


def test_check_fails_on_a_stale_diagram(tmp_path, monkeypatch):
    """--check is honest: a diagram that differs from the code's fails with one line."""
    architecture = _script("architecture")
    doc = tmp_path / "architecture.md"
    text = architecture.DOC.read_text(encoding="utf-8")
    doc.write_text(text.replace("flowchart TB", "flowchart LR"), encoding="utf-8")
    monkeypatch.setattr(architecture, "DOC", doc)
    monkeypatch.setattr(architecture, "ROOT", tmp_path)
    assert architecture.main(["--check"]) == 1
    doc.write_text("no markers", encoding="utf-8")
    assert architecture.main(["--check"]) == 1


def test_size_table_check_allows_a_small_drift_only(tmp_path, monkeypatch):
    """--check accepts the size table within 1 % of the counts (an edit of a few lines must not
    fail the suite), and fails one further off."""
    architecture = _script("architecture")
    now = architecture.size_table()
    # the doc as it would be written now (the committed one may already drift within 1 %)
    text = architecture.render(architecture.DOC.read_text(encoding="utf-8"),
                               architecture.diagram()[0], now)
    doc = tmp_path / "architecture.md"
    monkeypatch.setattr(architecture, "DOC", doc)
    monkeypatch.setattr(architecture, "ROOT", tmp_path)
    lines = architecture._numbers(now)[1]
    for factor, status in ((1.004, 0), (1.05, 1)):
        drifted = now.replace(f"{lines / 1000:.1f}k", f"{lines * factor / 1000:.1f}k")
        assert drifted != now
        doc.write_text(text.replace(now, drifted), encoding="utf-8")
        assert architecture.main(["--check"]) == status, factor


def test_unknown_blender_module_goes_in_other():
    architecture = _script("architecture")
    assert architecture.group_of("hazy_gloss.blender.brand_new")[1] == "other"
    assert architecture.group_of("hazy_gloss.blender.model.layer")[1] == "model"
    assert architecture.group_of("hazy_gloss.newfolder.x", {"hazy_gloss.newfolder"})[1] == "newfolder"


def test_parameter_tables_are_current():
    """docs/parameters.md's tables are what scripts/parameter_table.py writes from the schema."""
    _check(TABLES)


def test_parameter_table_check_fails_on_a_stale_table(tmp_path, monkeypatch):
    parameter_table = _script("parameter_table")
    doc = tmp_path / "parameters.md"
    text = parameter_table.DOC.read_text(encoding="utf-8")
    doc.write_text(text.replace("| r_c |", "| r |", 1), encoding="utf-8")
    monkeypatch.setattr(parameter_table, "DOC", doc)
    monkeypatch.setattr(parameter_table, "ROOT", tmp_path)
    assert parameter_table.main(["--check"]) == 1
    assert parameter_table.main([]) == 0 and parameter_table.main(["--check"]) == 0
    assert doc.read_text(encoding="utf-8") == text
    doc.write_text("no markers", encoding="utf-8")
    assert parameter_table.main(["--check"]) == 1
