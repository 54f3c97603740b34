"""Full 6x6 section stiffness (``stiffness = { matrix = ... }``) and saving scenes built
with NumPy values."""
import numpy as np
import pytest

from simsoft_jax.scene import Scene, load_scene, save_scene


def numpy_scene():
    """A scene dictionary holding NumPy scalars (np.float64, np.int64, np.str_, np.bool_)
    and arrays, as one builds it in Python."""
    return {
        "name": np.str_("numpy_built"),
        "solver": {"kind": "static", "tolerance": np.float64(1e-9),
                   "load_steps": np.int64(3)},
        "gravity": {"vector": np.array([0.0, 0.0, -9.81])},
        "rods": [{"name": "arm", "material": "aluminum_7075",
                  "section": {"shape": "rectangle", "width": np.float64(0.4712345678901234),
                              "height": np.float32(0.25)},
                  "elements": np.int32(4),
                  "geometry": {"kind": "straight", "length": np.float64(2.0)},
                  "base": {"position": np.zeros(3), "rotation": np.array([0.1, 0.0, 0.0])}}],
        "constraints": [{"kind": "clamp", "rod": "arm", "node": np.int64(0)}],
        "loads": [{"kind": "force", "rod": "arm", "node": np.int64(-1),
                   "vector": np.array([0.0, np.float64(1.5), -2.0]),
                   "profile": {"kind": "table", "t": np.linspace(0.0, 1.0, 3),
                               "scale": [np.float64(0.0), 0.5, np.float16(1.0)]}}],
    }


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_save_scene_round_trips_numpy_values(tmp_path, suffix):
    scene = Scene.from_dict(numpy_scene())
    raw = scene.to_dict()
    # only plain Python types survive validation (np.float64 is a float subclass)
    stack = [raw]
    while stack:
        item = stack.pop()
        if isinstance(item, dict):
            stack.extend(item.values())
        elif isinstance(item, list):
            stack.extend(item)
        else:
            assert type(item) in (str, int, float, bool), (type(item), item)
    path = tmp_path / f"scene{suffix}"
    save_scene(scene, path)
    text = path.read_text()
    assert "np." not in text and "array(" not in text
    again = load_scene(path)
    assert again.to_dict() == raw
    assert again.replace(source=None) == scene
    assert raw["rods"][0]["section"]["width"] == 0.4712345678901234   # exact round trip
    assert raw["rods"][0]["elements"] == 4 and raw["name"] == "numpy_built"
