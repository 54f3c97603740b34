"""Output safety (issue 17): the output path is checked before solving, result files are
written atomically, an existing file needs --force, and JSON result files are strict
(no NaN / Infinity tokens).

The solved scene is tests/test_run_cli.py's cantilever (same structure: one compilation
per process); its tip deflection is checked against Euler-Bernoulli, F L^3 / (3 E I_y),
within 1.5e-3 (the 16-element discretization and shear, see that file).
"""
import json
import os

import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax import cli
from simsoft_jax.pipeline import output
from test_run_cli import F, euler_bernoulli_tip, scene_dict


def strict_json(text):
    def reject(token):
        raise ValueError(f"non-standard JSON token {token}")
    return json.loads(text, parse_constant=reject)


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("scene") / "cantilever.json"
    path.write_text(json.dumps(scene_dict()))
    return path


@pytest.fixture
def no_solve(monkeypatch):
    """Any solve fails the test: the output checks must come first."""
    def forbidden(*args, **kwargs):
        raise AssertionError("solved before the output path was checked")
    monkeypatch.setattr("simsoft_jax.pipeline.results.run", forbidden)


def tip_z(path):
    return strict_json(path.read_text())["rods"]["beam"]["positions"][-1][2]


@pytest.mark.parametrize("name, message", [
    ("missing/out.json", "does not exist"),
    ("out.csv", "unsupported suffix '.csv'"),
    ("out", "unsupported suffix ''"),
])
def test_bad_output_path_exits_2_before_solving(scene_file, tmp_path, capsys, no_solve,
                                               name, message):
    code = cli.main(["run", str(scene_file), "-o", str(tmp_path / name)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and err[0].startswith("error: output:") and message in err[0]


def test_read_only_folder_exits_2_before_solving(scene_file, tmp_path, capsys, no_solve,
                                                 monkeypatch):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    if os.access(folder, os.W_OK):  # root ignores the mode bits: emulate a read-only mount
        monkeypatch.setattr(output.os, "access", lambda path, mode: False)
    code = cli.main(["run", str(scene_file), "-o", str(folder / "out.json")])
    folder.chmod(0o755)
    assert code == 2
    assert "is not writable" in capsys.readouterr().err


def test_existing_file_needs_force(scene_file, tmp_path, capsys, monkeypatch):
    out = tmp_path / "out.json"
    out.write_text("old content\n")
    with monkeypatch.context() as m:
        m.setattr("simsoft_jax.pipeline.results.run",
                  lambda *a, **k: pytest.fail("solved although the output exists"))
        assert cli.main(["run", str(scene_file), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "exists; pass --force" in err
    assert out.read_text() == "old content\n"
    assert cli.main(["run", str(scene_file), "-o", str(out), "--force"]) == 0
    expected = euler_bernoulli_tip(F)
    assert abs(-tip_z(out) - expected) / expected < 1.5e-3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.json"]  # no temporary left


@pytest.fixture(scope="module")
def result():
    return sj.run(scene_dict())


def test_failed_json_write_keeps_the_old_file(result, tmp_path, monkeypatch):
    """json.dumps raising (as an interrupt would) after part of the file is written
    leaves the old file byte for byte."""
    import json
    out = tmp_path / "out.json"
    result.save(out)
    before = out.read_bytes()
    calls, dumps = [], json.dumps

    def interrupted(*args, **kwargs):
        calls.append(1)
        if len(calls) == 5:   # the file written piece by piece: some pieces are out
            raise KeyboardInterrupt
        return dumps(*args, **kwargs)
    monkeypatch.setattr("simsoft_jax.pipeline.output.json.dumps", interrupted)
    with pytest.raises(KeyboardInterrupt):
        result.save(out)
    assert out.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["out.json"]
    expected = euler_bernoulli_tip(F)
    assert abs(-tip_z(out) - expected) / expected < 1.5e-3


def test_disk_full_mid_npz_keeps_the_old_file(result, tmp_path, monkeypatch):
    """np.savez writing part of the archive and then failing (a full disk) leaves the old
    archive intact and readable; through the CLI that is exit 2 with one line."""
    out = tmp_path / "out.npz"
    result.save(out)
    before = out.read_bytes()
    real_savez = np.savez

    def disk_full(fh, **arrays):
        fh.write(b"PK\x03\x04 partial")
        raise OSError(28, "No space left on device")
    monkeypatch.setattr("simsoft_jax.pipeline.results.np.savez", disk_full)
    with pytest.raises(OSError):
        result.save(out)
    assert out.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["out.npz"]
    with np.load(out) as z:
        np.testing.assert_array_equal(z["beam/positions"], result.positions("beam"))
    monkeypatch.setattr("simsoft_jax.pipeline.results.np.savez", real_savez)


def test_disk_full_through_the_cli(scene_file, tmp_path, capsys, monkeypatch):
    out = tmp_path / "out.json"
    out.write_text("{}")

    def disk_full(fh, *args, **kwargs):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr("simsoft_jax.pipeline.output.os.fsync", disk_full)
    assert cli.main(["run", str(scene_file), "-o", str(out), "--force"]) == 2
    err = capsys.readouterr().err
    assert "No space left on device" in err and "unchanged" in err
    assert out.read_text() == "{}"


def test_nonfinite_values_are_written_as_null(result, tmp_path, monkeypatch):
    """A result holding NaN and infinities (as a blown-up solve does) gives strict JSON:
    each non-finite number is null and the message counts them (3 + 1 + 1 here)."""
    monkeypatch.setattr(result, "_p", result._p.copy())
    result._p[5] = np.nan
    monkeypatch.setattr(result, "residual_norm", float("inf"))
    monkeypatch.setattr(result, "wall_time_s", float("nan"))
    out = result.save(tmp_path / "nan.json")
    d = strict_json(out.read_text())
    assert d["rods"]["beam"]["positions"][5] == [None, None, None]
    assert d["rods"]["beam"]["positions"][4] == result.positions("beam")[4].tolist()
    assert d["residual_norm"] is None and d["wall_time_s"] is None
    assert d["message"].endswith("(5 non-finite values written as null)")


def test_failed_solve_with_infinite_residual_gives_strict_json(tmp_path):
    """One load step, one Newton iteration, every level to the final tolerance, a tip
    moment bending the rod 8 rad: no load level is ever accepted, so the residual at the
    last accepted level is infinite; the file writes null there and the status says why
    the solve ended."""
    E, W, H, L = 71.7e9, 3.2024e-3, 12.377e-3, 0.508
    d = scene_dict(moment=(0.0, 0.0, 8.0 * E * H * W**3 / 12.0 / L), max_iterations=1,
                   load_steps=1, level_tolerance=0.0)
    r = sj.run(d)
    assert not r.converged and r.load_level == 0.0 and np.isinf(r.residual_norm)
    data = strict_json(r.save(tmp_path / "failed.json").read_text())
    assert data["residual_norm"] is None and data["failed_at"]["residual_norm"] is None
    assert data["status"] != "converged" and "non-finite value" in data["message"]
    np.testing.assert_array_equal(data["rods"]["beam"]["positions"], r.positions("beam"))
