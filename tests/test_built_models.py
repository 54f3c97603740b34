"""simsoft_jax.model.built_models: the Model of a scene kept by content, an immutable Scene
object recognised by identity, and every way such a scene can still change noticed."""
import json

import numpy as np
import pytest

import simsoft_jax as sj
from conftest import arc, pure_bending_scene
from simsoft_jax.model import built_models


def cantilever(moment):
    return pure_bending_scene(moment, EI=2.0)


S = np.linspace(0.0, 1.0, 5)


def no_pickling(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("the scene was pickled again")
    monkeypatch.setattr(built_models.pickle, "dumps", refuse)


def test_the_same_immutable_scene_is_found_without_a_digest(monkeypatch):
    scene = sj.Scene.from_dict(cantilever(1.0))
    model = built_models.model_of(scene)
    no_pickling(monkeypatch)
    assert built_models.model_of(scene) is model
    monkeypatch.undo()
    # an equal scene parsed again is another object: found by its digest
    assert built_models.model_of(sj.Scene.from_dict(cantilever(1.0))) is model


def test_an_array_made_writable_and_changed_builds_a_new_model():
    """Unlocking a read-only array of a remembered scene and changing it in place is
    noticed: the new model bends by the new moment (exact pure bending)."""
    scene = sj.Scene.from_dict(cantilever(1.0))
    first = sj.run(scene)
    np.testing.assert_allclose(first.positions("rod"), arc(0.5, S)[0], rtol=0, atol=1e-9)
    vector = scene.loads[0].vector
    assert not vector.flags.writeable
    vector.setflags(write=True)
    vector[1] = 2.0
    second = sj.run(scene)
    assert second.model is not first.model
    np.testing.assert_allclose(second.positions("rod"), arc(1.0, S)[0], rtol=0, atol=1e-9)


def test_a_scene_with_a_writable_array_is_digested_at_every_call():
    """A scene given a writable array (``Scene.replace``) is never trusted by identity: an
    in-place change of its gravity reaches the model."""
    scene = sj.Scene.from_dict(cantilever(1.0)).replace(gravity=np.array([0.0, 0.0, -9.81]))
    model = built_models.model_of(scene)
    assert built_models.model_of(scene) is model
    scene.gravity[2] = -1.62
    moon = built_models.model_of(scene)
    assert moon is not model
    np.testing.assert_array_equal(np.asarray(moon.gravity), [0.0, 0.0, -1.62])


def test_a_changed_section_dict_is_noticed():
    """The flat dicts of a scene (section dimensions) are compared with their copy at each
    call by identity: a change gives another digest and another model."""
    d = cantilever(1.0)
    rod = d["rods"][0]
    del rod["stiffness"], rod["inertia"]
    rod.update(section={"shape": "circle", "diameter": 0.01}, material="spring_steel")
    scene = sj.Scene.from_dict(d)
    model = built_models.model_of(scene)
    assert built_models.model_of(scene) is model
    scene.rods[0].section.dimensions["diameter"] = 0.02
    assert built_models.model_of(scene) is not model


def test_fields_no_model_is_built_from_share_the_model():
    """``raw`` (the input as given) and ``source`` do not enter the digest."""
    scene = sj.Scene.from_dict(cantilever(1.0))
    model = built_models.model_of(scene)
    assert built_models.model_of(scene.replace(source="elsewhere.toml", raw={})) is model


def test_lru_drops_the_least_recently_used():
    cache = built_models.Lru(size=2)
    cache["a"], cache["b"] = 1, 2
    assert cache["a"] == 1          # read: "b" is now the least recently used
    cache["c"] = 3
    assert list(cache) == ["a", "c"]


def write(path, d):
    path.write_text(json.dumps(d))
    return path


def test_a_scene_file_is_parsed_once_per_content(tmp_path, monkeypatch):
    """``sj.run(path)`` parses a file again only when its bytes change: a rewrite of the
    same size (one digit) is noticed and the result follows the new moment (exact pure
    bending)."""
    path = write(tmp_path / "bend.json", cantilever(1.0))
    first = built_models.scene_of(path)
    assert built_models.scene_of(path) is first
    calls = []
    monkeypatch.setattr(built_models, "load_scene",
                        lambda p: calls.append(p) or sj.load_scene(p))
    assert sj.run(path).model is built_models.model_of(first) and calls == []
    write(path, cantilever(2.0))
    result = sj.run(path)
    assert len(calls) == 1
    np.testing.assert_allclose(result.positions("rod"), arc(1.0, S)[0], rtol=0, atol=1e-9)


def test_a_changed_table_file_parses_the_scene_again(tmp_path):
    """A file the scene reads (a load profile table) is part of its content: changing it
    alone gives a new Scene whose profile holds the new numbers."""
    d = cantilever(1.0)
    (tmp_path / "law.csv").write_text("0.0, 0.0\n1.0, 1.0\n")
    d["loads"][0]["profile"] = {"kind": "table", "file": "law.csv"}
    path = write(tmp_path / "bend.json", d)
    first = built_models.scene_of(path)
    assert built_models.scene_of(path) is first
    (tmp_path / "law.csv").write_text("0.0, 0.0\n1.0, 3.0\n")
    again = built_models.scene_of(path)
    assert again is not first
    np.testing.assert_array_equal(first.loads[0].profile.scale, [0.0, 1.0])
    np.testing.assert_array_equal(again.loads[0].profile.scale, [0.0, 3.0])


def test_a_bad_file_raises_each_time_and_keeps_nothing(tmp_path):
    path = tmp_path / "bad.json"
    path.write_text("{not json")
    for _ in range(2):
        with pytest.raises(ValueError, match="not valid JSON"):
            built_models.scene_of(path)
