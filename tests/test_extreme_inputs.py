"""Extreme inputs the validator accepts end quickly with a reason (issue 17): the scenes
that used to hang (a length of 1e300, a load of 1e300 N, gravity of 1e200 m/s^2) stop
at load level 0 with a status and a message, and their result files are strict JSON; a
length of 1e-300 m is rejected (its elements have no representable length)."""
import json
import warnings

import numpy as np
import pytest

import simsoft_jax as sj
from test_run_cli import scene_dict


def strict(text):
    def reject(token):
        raise ValueError(token)
    return json.loads(text, parse_constant=reject)


@pytest.mark.parametrize("change", [
    lambda d: d["rods"][0]["geometry"].update(length=1e300),
    lambda d: d["loads"][0].update(vector=[0.0, 0.0, -1e300]),
    lambda d: d.update(gravity={"vector": [0.0, 0.0, -1e200]}),
], ids=["length 1e300", "load 1e300", "gravity 1e200"])
def test_overflowing_scenes_end_with_a_reason(change, tmp_path):
    d = scene_dict()
    change(d)
    with warnings.catch_warnings():      # NumPy overflow warnings while building the model
        warnings.simplefilter("ignore", RuntimeWarning)
        r = sj.run(d)
    assert not r.converged and r.load_level == 0.0
    # it ends by the step-halving rule, not by a long search: no step is ever accepted
    # and the halvings from 1/load_steps down to min_step_fraction are all it tries
    settings = sj.StaticSettings()
    assert int(r.raw.load_steps) == 0
    assert int(r.raw.step_failures) <= 1 - np.log2(settings.min_step_fraction)
    assert r.status in ("step_too_small", "max_attempts", "nonfinite")
    assert r.message.startswith("static solve failed at load level 0:")
    data = strict(r.save(tmp_path / "r.json").read_text())
    assert data["converged"] is False and data["status"] == r.status


def test_tiny_length_is_rejected():
    d = scene_dict()
    d["rods"][0]["geometry"]["length"] = 1e-300
    with pytest.raises(ValueError, match=r"^rods\[0\]\.geometry: element 0 of 16 has zero "
                                         r"length"):
        sj.Scene.from_dict(d)
