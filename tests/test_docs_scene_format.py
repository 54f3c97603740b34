"""docs/scene-format.md keeps up with the scene parser.

The accepted key sets are read from the code (the allowed-key tuples that
``simsoft_jax/scene/scene.py`` and its section parsers (``scene_rods.py``, ``scene_contact.py``,
...: ``SOURCES``) pass to ``check_keys``, their module-level ``*_KEYS`` tables, and the
options they pass to ``choice``), so a key added to the parser without a line in
the reference makes this test fail. The complete example scenes in the document must
validate, and the example error messages must be what the validator prints.
"""
from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

import pytest

from simsoft_jax.scene import scene as scene_module
from simsoft_jax.scene import scene_rods
from simsoft_jax.scene.scene import Scene

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
DOC_PATH = ROOT / "docs" / "scene-format.md"
DOC = DOC_PATH.read_text(encoding="utf-8")
SOURCES = [Path(scene_module.__file__)] + [Path(scene_module.__file__).with_name(name) for name in
                                            ("scene_rods.py", "scene_initial.py", "key_checks.py",
                                             "scene_contact.py", "scene_actuators.py",
                                             "scene_attachments.py", "scene_mechanisms.py",
                                             "scene_fields.py")]


def _strings(node: ast.AST, names: dict[str, ast.AST], part: str = "all") -> set[str]:
    """String constants in an expression. Names are followed to their (module or local)
    assignment; ``*keys``, ``a if c else b`` and ``tuple(...)`` are looked through. For a
    dict, ``part`` picks its keys, its values or both; ``tuple(d)`` gives a dict's keys and
    ``d[k]`` its values."""
    def rec(n, part=part):
        return _strings(n, names, part)
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return {node.value}
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        return set().union(set(), *(rec(e) for e in node.elts))
    if isinstance(node, ast.Dict):
        keys = set().union(set(), *(rec(k) for k in node.keys if k is not None))
        values = set().union(set(), *(rec(v) for v in node.values))
        return {"keys": keys, "values": values, "all": keys | values}[part]
    if isinstance(node, ast.Starred):
        return rec(node.value)
    if isinstance(node, ast.IfExp):
        return rec(node.body) | rec(node.orelse)
    if isinstance(node, ast.Name) and node.id in names:
        return rec(names[node.id])
    if isinstance(node, ast.Subscript):
        return rec(node.value, "values")
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "tuple":
        return set().union(set(), *(rec(a, "keys") for a in node.args))
    return set()


def _code_sets() -> tuple[set[str], set[str]]:
    """(keys, option values) the parser accepts, read from the source."""
    keys: set[str] = set()
    options: set[str] = set()
    for path in SOURCES:
        tree = ast.parse(path.read_text(encoding="utf-8"))
        module = {t.id: n.value for n in tree.body if isinstance(n, ast.Assign)
                  for t in n.targets if isinstance(t, ast.Name)}
        for name, value in module.items():
            if name.endswith("_KEYS"):         # tuples of keys, or {kind: keys}
                keys |= _strings(value, module, "values")
                options |= _strings(value, module, "keys") if isinstance(value, ast.Dict) else set()
        if "SECTIONS" in module:                # {shape: (builder, (keys...))}
            options |= _strings(module["SECTIONS"], module, "keys")
            keys |= _strings(module["SECTIONS"], module, "values")
        for func in ast.walk(tree):
            if not isinstance(func, ast.FunctionDef):
                continue
            names = dict(module)
            names.update({t.id: n.value for n in ast.walk(func) if isinstance(n, ast.Assign)
                          for t in n.targets if isinstance(t, ast.Name)})
            for node in ast.walk(func):
                if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)):
                    continue
                if node.func.id == "check_keys" and len(node.args) >= 3:
                    keys |= _strings(node.args[2], names)
                    for kw in node.keywords:
                        if kw.arg == "required":
                            keys |= _strings(kw.value, names)
                elif node.func.id == "require" and len(node.args) >= 3:
                    keys |= _strings(node.args[2], names)
                elif node.func.id == "choice" and len(node.args) >= 3:
                    options |= _strings(node.args[2], names)
    return keys, options


def _mentions_key(key: str) -> bool:
    return f"`{key}`" in DOC or re.search(rf"(^|[\s{{,]){re.escape(key)}\s*=", DOC, re.M) is not None


def test_doc_exists_and_readme_links_it():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "docs/scene-format.md" in readme
    assert "../shared/spec/scene-format.md" not in readme


@pytest.mark.parametrize("key", scene_module._TOP_KEYS)
def test_every_top_level_key_is_documented(key):
    assert f"`{key}`" in DOC, f"top-level key {key!r} (scene._TOP_KEYS) missing from {DOC_PATH}"


@pytest.mark.parametrize("key", scene_rods.ROD_KEYS)
def test_every_rod_key_is_documented(key):
    assert f"`{key}`" in DOC, f"rod key {key!r} (scene_rods.ROD_KEYS) missing from {DOC_PATH}"


def test_every_accepted_key_and_option_is_documented():
    keys, options = _code_sets()
    assert {"solver", "rods", "elements", "slides_along", "angle_deg", "rate"} <= keys
    assert {"static", "dynamic", "clamp", "drive", "lumped", "smoothstep", "tube"} <= options
    missing_keys = sorted(k for k in keys if not _mentions_key(k))
    missing_options = sorted(o for o in options if f'"{o}"' not in DOC and f"`{o}`" not in DOC)
    assert not missing_keys, f"keys accepted by scene.py but not in {DOC_PATH.name}: {missing_keys}"
    assert not missing_options, (f"values accepted by scene.py but not in {DOC_PATH.name}: "
                                 f"{missing_options}")


def _complete_examples() -> list[str]:
    return re.findall(r"<!-- complete-scene -->\s*```toml\n(.*?)```", DOC, re.S)


def test_complete_examples_validate():
    examples = _complete_examples()
    assert len(examples) >= 2
    for text in examples:
        Scene.from_dict(tomllib.loads(text))


_VALID = {"solver": {"kind": "static"},
          "rods": [{"name": "arm", "material": "aluminum_7075",
                    "section": {"shape": "rectangle", "width": 1e-2, "height": 1e-2},
                    "elements": 4, "geometry": {"kind": "straight", "length": 0.5}}],
          "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}]}


def _message(change) -> str:
    import copy
    d = copy.deepcopy(_VALID)
    change(d)
    with pytest.raises(ValueError) as err:
        Scene.from_dict(d)
    return str(err.value)


def test_example_error_messages_are_what_the_validator_prints():
    width = _message(lambda d: d["rods"][0]["section"].update(width=-1.0))
    unknown = _message(lambda d: d.update(colour="red"))
    assert width in DOC, width
    assert unknown in DOC, unknown
