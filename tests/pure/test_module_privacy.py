# SPDX-License-Identifier: GPL-3.0-or-later
"""Each module owns its inside: no module of the package imports another's private name (``from
x import _y`` or ``x._y``), and no module (other than a package's ``__init__``) only re-exports
what others define.  Each rule is also run on a small made-up package, so that it can fail."""
import ast
import pathlib

import pytest

PACKAGE = pathlib.Path(__file__).resolve().parents[2] / "hazy_gloss"


def _private(name):
    return name.startswith("_") and not name.startswith("__")


def private_imports(source):
    """The private names ``source`` takes from other modules: ``from m import _x`` and
    ``alias._x`` where ``alias`` is bound by an import."""
    tree = ast.parse(source)
    found, aliases = [], set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            for a in node.names:
                if _private(a.name):
                    found.append(f"from {'.' * node.level}{node.module or ''} import {a.name}")
                aliases.add(a.asname or a.name)
        elif isinstance(node, ast.Import):
            for a in node.names:
                aliases.add(a.asname or a.name.split(".")[0])
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and _private(node.attr) and \
                isinstance(node.value, ast.Name) and node.value.id in aliases:
            found.append(f"{node.value.id}.{node.attr}")
    return found


def only_reexports(source):
    """True for a module whose code is imports alone (besides its docstring and ``__all__``)."""
    body = ast.parse(source).body
    if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
        body = body[1:]
    rest = [n for n in body if not isinstance(n, (ast.Import, ast.ImportFrom)) and not (
        isinstance(n, ast.Assign) and [getattr(t, "id", None) for t in n.targets] == ["__all__"])]
    return bool(body) and not rest


def _modules():
    return sorted(p for p in PACKAGE.rglob("*.py"))


def test_the_rules_can_fail():
    assert private_imports("from .a import _b\n") == ["from .a import _b"]
    assert private_imports("from . import a\nx = a._b\n") == ["a._b"]
    assert private_imports("import numpy as np\nx = np._NoValue\n") == ["np._NoValue"]
    assert private_imports("from .a import b\nclass C:\n    def f(self):\n        return self._x\n") == []
    assert only_reexports('"""Doc."""\nfrom .a import b, c\n__all__ = ("b", "c")\n')
    assert not only_reexports("from .a import b\n\ndef f():\n    return b\n")


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_private_name_crosses_a_module(path):
    assert private_imports(path.read_text(encoding="utf-8")) == []


@pytest.mark.parametrize("path", [p for p in _modules() if p.name != "__init__.py"],
                         ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_module_only_reexports(path):
    assert not only_reexports(path.read_text(encoding="utf-8"))


def _all_of(source):
    """A module's ``__all__`` (None when it has none)."""
    for node in ast.parse(source).body:
        if isinstance(node, ast.Assign) and [getattr(t, "id", None) for t in node.targets] == ["__all__"]:
            return tuple(ast.literal_eval(node.value))
    return None


def _module_path(importer, node):
    """The file ``from ... import`` in ``importer`` reads names from (None outside the package)."""
    if node.level:
        base = importer.parent
        for _ in range(node.level - 1):
            base = base.parent
    elif (node.module or "").split(".")[0] == "hazy_gloss":
        base, node = PACKAGE.parent, ast.ImportFrom(module=node.module, level=0)
    else:
        return None
    target = base.joinpath(*(node.module.split(".") if node.module else []))
    for cand in (target.with_suffix(".py"), target / "__init__.py"):
        if cand.is_file():
            return cand
    return None


def test_public_names_are_the_modules_all():
    """Every module but the package entry points declares ``__all__``; what another module
    imports from it by name is in it (a submodule is not a name)."""
    missing, outside = [], []
    alls = {}
    for path in _modules():
        if path.name in ("__init__.py", "__main__.py"):
            continue
        names = _all_of(path.read_text(encoding="utf-8"))
        if names is None:
            missing.append(str(path.relative_to(PACKAGE)))
        alls[path] = names or ()
    for path in _modules():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.ImportFrom):
                continue
            src = _module_path(path, node)
            if src is None or src not in alls:
                continue
            for a in node.names:
                if a.name not in alls[src] and not (src.parent / a.name).exists() and \
                        not (src.parent / f"{a.name}.py").exists():
                    outside.append(f"{path.relative_to(PACKAGE)}: {a.name} from "
                                   f"{src.relative_to(PACKAGE)}")
    assert not missing, missing
    assert not outside, outside
