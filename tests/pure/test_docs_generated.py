# SPDX-License-Identifier: GPL-3.0-or-later
"""The generated parts of the docs are up to date: docs/architecture.md's import diagram is what
scripts/architecture.py draws from the code now (its ``--check``)."""
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "architecture.py"


def test_architecture_diagram_is_current():
    run = subprocess.run([sys.executable, str(SCRIPT), "--check"], capture_output=True,
                         text=True, cwd=ROOT, timeout=120)
    assert run.returncode == 0, run.stderr.strip() or run.stdout.strip()
    assert "not in ROLES" not in run.stderr, run.stderr.strip()


def test_check_fails_on_a_stale_diagram(tmp_path, monkeypatch):
    """--check is honest: a diagram that differs from the code's fails with one line."""
    sys.path.insert(0, str(SCRIPT.parent))
    try:
        import architecture
    finally:
        sys.path.remove(str(SCRIPT.parent))
    doc = tmp_path / "architecture.md"
    text = architecture.DOC.read_text(encoding="utf-8")
    doc.write_text(text.replace("flowchart TB", "flowchart LR"), encoding="utf-8")
    monkeypatch.setattr(architecture, "DOC", doc)
    monkeypatch.setattr(architecture, "ROOT", tmp_path)
    assert architecture.main(["--check"]) == 1
    doc.write_text("no markers", encoding="utf-8")
    assert architecture.main(["--check"]) == 1


def test_unknown_blender_module_goes_in_other():
    sys.path.insert(0, str(SCRIPT.parent))
    try:
        import architecture
    finally:
        sys.path.remove(str(SCRIPT.parent))
    assert architecture.group_of("hazy_gloss.blender.brand_new")[1] == "other"
    assert architecture.group_of("hazy_gloss.blender.model.layer")[1] == "model"
    assert architecture.group_of("hazy_gloss.newfolder.x", {"hazy_gloss.newfolder"})[1] == "newfolder"
