"""The package's layers (README, "Layout"): no module imports a layer to its right, and
no module imports another module's private (``_name``) names. Read from the source with
``ast``; imports under ``if TYPE_CHECKING:`` (type names only) are not imports at run
time and are skipped."""
from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "simsoft_jax"
# left to right: a module may import its own layer and those to its left
ORDER = ("math", "scene", "physics", "model", "couplings", "solvers", "analysis",
         "studies", "pipeline", "apps")


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _runtime_imports(tree: ast.Module):
    """Import nodes outside ``if TYPE_CHECKING:`` blocks."""
    skipped = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and getattr(node.test, "id", None) == "TYPE_CHECKING":
            skipped.update(id(n) for n in ast.walk(node))
    return [n for n in ast.walk(tree)
            if isinstance(n, (ast.Import, ast.ImportFrom)) and id(n) not in skipped]


def _imports(path: Path):
    """``(line, imported module, names)`` of the package's run-time imports in ``path``."""
    module = _module_name(path)
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    for node in _runtime_imports(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name, ()
            continue
        base = package.split(".")
        if node.level:
            base = base[:len(base) - (node.level - 1)]
            target = ".".join(base + ([node.module] if node.module else []))
        else:
            target = node.module or ""
        yield node.lineno, target, tuple(alias.name for alias in node.names)


def _layer(module: str):
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[1] in ORDER else None


def _sources():
    return sorted(PACKAGE.rglob("*.py"))


def test_no_module_imports_a_layer_to_its_right():
    wrong = []
    for path in _sources():
        me = _layer(_module_name(path))
        for line, target, names in _imports(path):
            if not target.startswith("simsoft_jax"):
                continue
            for full in [target] + [f"{target}.{n}" for n in names]:
                other = _layer(full)
                if me and other and ORDER.index(other) > ORDER.index(me):
                    wrong.append(f"{path.relative_to(PACKAGE)}:{line} imports {full}")
                    break
    assert not wrong, "imports against the layer order:\n" + "\n".join(wrong)


def test_no_private_name_crosses_modules():
    wrong = []
    for path in _sources():
        for line, target, names in _imports(path):
            if not target.startswith("simsoft_jax"):
                continue
            private = [n for n in names if n.startswith("_") and not n.startswith("__")]
            if private or any(p.startswith("_") for p in target.split(".")[1:]):
                wrong.append(f"{path.relative_to(PACKAGE)}:{line} imports "
                             f"{target} {private}")
    assert not wrong, "private names imported across modules:\n" + "\n".join(wrong)


def test_the_checks_see_a_wrong_import(tmp_path, monkeypatch):
    """The layer check finds an import to the right (so that it can fail)."""
    fake = tmp_path / "simsoft_jax"
    (fake / "math").mkdir(parents=True)
    (fake / "math" / "bad.py").write_text("from ..solvers import newton\n")
    monkeypatch.setattr(__import__(__name__), "PACKAGE", fake)
    try:
        test_no_module_imports_a_layer_to_its_right()
    except AssertionError as error:
        assert "math/bad.py:1 imports simsoft_jax.solvers" in str(error)
    else:
        raise AssertionError("the wrong import was not found")
