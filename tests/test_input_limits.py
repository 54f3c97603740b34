"""Input limits: scenes nested too deeply and absurdly long keys give one short error."""
import json

import pytest

import simsoft_jax as sj
from simsoft_jax.scene.key_checks import MAX_DEPTH

BEAM = {"solver": {"kind": "static"},
        "rods": [{"name": "beam", "material": "aluminum_7075",
                  "section": {"shape": "circle", "diameter": 0.01},
                  "elements": 2, "geometry": {"kind": "straight", "length": 1.0}}],
        "constraints": [{"kind": "clamp", "rod": "beam", "node": 0}]}


def nested(levels):
    """A list nested ``levels`` deep: [[[...]]]."""
    value = 0.0
    for _ in range(levels):
        value = [value]
    return value


@pytest.mark.parametrize("suffix", [".json", ".toml"])
def test_file_nested_past_the_parsers_recursion_is_one_error(tmp_path, suffix):
    path = tmp_path / f"deep{suffix}"
    deep = "[" * 100000 + "]" * 100000
    path.write_text(deep if suffix == ".json" else f"x = {deep}\n")
    with pytest.raises(ValueError) as err:
        sj.load_scene(path)
    assert "nested too deeply" in str(err.value) and str(MAX_DEPTH) in str(err.value)
    assert err.value.__suppress_context__              # no RecursionError traceback


@pytest.mark.parametrize("suffix", [".json", ".toml"])
def test_file_nested_past_the_limit_is_rejected(tmp_path, suffix):
    d = dict(BEAM, extra=nested(200))               # readable by the parsers, too deep
    path = tmp_path / f"deep{suffix}"
    text = json.dumps(d) if suffix == ".json" else None
    if suffix == ".toml":
        text = 'extra = ' + json.dumps(nested(200)) + '\n[solver]\nkind = "static"\n'
    path.write_text(text)
    with pytest.raises(ValueError, match=f"extra(\\[0\\])+.*nested more than {MAX_DEPTH} "
                                         "levels deep") as err:
        sj.load_scene(path)
    assert len(str(err.value)) < 250


def test_nesting_limit_applies_to_dicts_too():
    assert MAX_DEPTH == 64
    sj.Scene.from_dict(BEAM)                         # depth 4: fine
    d = dict(BEAM, extra=nested(MAX_DEPTH - 1))      # 64 levels with the scene table
    with pytest.raises(ValueError, match="unknown key"):
        sj.Scene.from_dict(d)
    d = dict(BEAM, extra=nested(MAX_DEPTH))          # 65 levels
    with pytest.raises(ValueError, match="nested more than 64 levels deep"):
        sj.Scene.from_dict(d)
    with pytest.raises(ValueError, match="nested more than 64 levels deep"):
        sj.Scene.from_dict(dict(BEAM, extra=nested(100000)))   # no RecursionError


def test_long_unknown_key_is_shortened_in_the_message():
    key = "k" * 10000
    d = dict(BEAM, rods=[dict(BEAM["rods"][0], **{key: 1})])
    with pytest.raises(ValueError) as err:
        sj.Scene.from_dict(d)
    message = str(err.value)
    assert message.startswith("rods[0]." + "k" * 40 + "...: unknown key")
    assert len(message) < 500
