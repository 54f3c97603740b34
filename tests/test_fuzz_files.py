"""Seeded fuzz of scene *files* (what ``simsoft-jax validate`` reads), fast lane.

About 600 malformed files made from the example scenes and a few hand-made ones, each
of one kind of damage: cut short, a byte changed or inserted (NUL, invalid UTF-8,
newline), a value replaced by a nasty one (400-digit numbers, 1e999, control-character
or megabyte strings, deep nesting, wrong types), a key repeated or renamed, a table
moved to the wrong place, a node index, count or file name out of range. Each file is
read by :func:`simsoft_jax.load_scene` under a time limit and must end one way:

* refused with one ``ValueError`` whose text is one printable line, at most a few
  thousand characters, starting with the file name or a key path, or
* accepted, and then :func:`simsoft_jax.build_model` (no compile, no solve) accepts it
  too: what validate accepts, run does not refuse for its input.

Anything else (another exception, a second line, a hang past the limit) fails the test,
listing every case that did. ``test_fuzz_counts`` prints the tally (``-s``).
"""
import copy
import json
import random
import re
import signal
import sys
import warnings

import pytest

import simsoft_jax as sj
from conftest import SCENES_DIR

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

SEED, COUNT, LIMIT_S = 38, 600, 20
KEY_PATH = r"^[^\s:]+: "   # a key path (its keys as written, control characters escaped)
NASTY = [10**400, -10**400, 1e308 * 10, "1e999", "", "\x00", "a\nerror: fake", "\x1b[2J",
         "x" * 1_000_000, [], {}, [[[[[]]]]], None, True, -1, 0, 2**63, -2**63 - 1,
         0.5, "rods", {"kind": "weird"}, [1, "a", None], float("nan")]


def _examples():
    out = []
    for path in sorted(SCENES_DIR.iterdir()):
        if path.suffix == ".json":
            out.append((path.name, json.loads(path.read_text())))
        elif path.suffix == ".toml":
            out.append((path.name, tomllib.loads(path.read_text())))
    return out


def _small(d):
    """Example scenes cut to few elements (the build stays cheap)."""
    d = copy.deepcopy(d)
    for rod in d.get("rods", []):
        if isinstance(rod, dict) and "segments" not in rod:
            rod["elements"] = 4
        if isinstance(rod, dict):
            geometry = rod.get("geometry", {})
            if geometry.get("kind") == "helix":
                geometry["turns"] = min(geometry.get("turns", 1), 1.0)
            rod.pop("initial", None)
    return d


def _paths(value, path=()):
    out = [path]
    if isinstance(value, dict):
        for key, item in value.items():
            out += _paths(item, path + (key,))
    elif isinstance(value, list):
        for i, item in enumerate(value):
            out += _paths(item, path + (i,))
    return out


def _at(d, path):
    for key in path:
        d = d[key]
    return d


def _structural(d, rng):
    """One change to the scene's tables (JSON text out, unless the change is text)."""
    d = copy.deepcopy(d)
    paths = [p for p in _paths(d) if p]
    path = rng.choice(paths)
    parent, key = _at(d, path[:-1]), path[-1]
    kind = rng.choice(["nasty", "nasty", "drop", "rename", "move", "index", "deep",
                       "duplicate", "negative_node"])
    if kind == "nasty":
        parent[key] = rng.choice(NASTY)
    elif kind == "drop":
        del parent[key]
    elif kind == "rename" and isinstance(key, str):
        parent[key + rng.choice(["_", "\n", "\x00", "s"])] = parent.pop(key)
    elif kind == "move":   # a table where another belongs
        other = _at(d, rng.choice(paths))
        parent[key] = copy.deepcopy(other)
    elif kind == "index":
        parent[key] = rng.choice([10**9, -10**9, 3.5, "0"])
    elif kind == "deep":   # nested arrays, as text (too deep for json.dumps)
        parent[key] = "__deep__"
        depth = rng.choice([70, 5000])
        return (json.dumps(d).replace('"__deep__"', "[" * depth + "0" + "]" * depth, 1),
                f"{kind} {depth} at {'.'.join(map(str, path))}")
    elif kind == "negative_node":
        for c in d.get("constraints", []) if isinstance(d.get("constraints"), list) else []:
            if isinstance(c, dict):
                c["node"] = -10**6
    elif kind == "duplicate" and isinstance(key, str):   # a repeated key, as text
        text = json.dumps(d)
        needle = json.dumps(key) + ":"
        at = text.find(needle)
        if at >= 0:
            return text[:at] + needle + " 1, " + text[at:], f"{kind} {key!r}"
    return json.dumps(d, allow_nan=True), f"{kind} at {'.'.join(map(str, path))}"


def _textual(text, rng):
    """One change to the bytes of a valid file."""
    data = text.encode()
    kind = rng.choice(["cut", "flip", "insert", "bom", "utf8"])
    at = rng.randrange(len(data))
    if kind == "cut":
        data = data[:at]
    elif kind == "flip":
        data = data[:at] + bytes([data[at] ^ (1 << rng.randrange(8))]) + data[at + 1:]
    elif kind == "insert":
        data = data[:at] + rng.choice([b"\x00", b"\n", b"}", b"]", b",", b"\"", b"=",
                                       b"[[", b"#"]) + data[at:]
    elif kind == "bom":
        data = b"\xef\xbb\xbf" + data
    else:
        data = data[:at] + b"\xff\xfe" + data[at:]
    return data, f"{kind} at byte {at}"


def _toml(d):
    from simsoft_jax.scene.key_checks import toml_document
    return toml_document(d)


def cases():
    rng = random.Random(SEED)
    bases = [(n, _small(d)) for n, d in _examples()]
    out = []
    for k in range(COUNT):
        name, d = rng.choice(bases)
        if rng.random() < 0.6:
            text, change = _structural(d, rng)
            out.append((f"{k}.json", text.encode("utf-8", "surrogatepass"), f"{name}: {change}"))
        else:
            suffix = rng.choice([".json", ".toml"])
            text = json.dumps(d) if suffix == ".json" else _toml(d)
            data, change = _textual(text, rng)
            out.append((f"{k}{suffix}", data, f"{name} as {suffix}: {change}"))
    for k, data in enumerate([b"", b"[]", b"1", b"\"scene\"", b"null", b"{}" * 3,
                              b"[" * 100_000, b"{\"a\":" * 100_000]):
        out.append((f"top{k}.json", data, f"top level {data[:12]!r}"))
    return out


class Hung(Exception):
    pass


def _alarm(signum, frame):
    raise Hung


def outcome(tmp_path, file, data):
    """"rejected", "accepted" or a failure text for one file."""
    path = tmp_path / file
    path.write_bytes(data)
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(LIMIT_S)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                scene = sj.load_scene(path)
            except ValueError as err:
                text = str(err)
                if "\n" in text or "\x00" in text or "\x1b" in text or len(text) > 2100:
                    return f"unreadable message: {text[:200]!r}"
                if not (text.startswith(str(path)) or re.match(KEY_PATH, text)):
                    return f"message names no key or file: {text[:200]!r}"
                return "rejected"
            try:
                sj.build_model(scene, device=False)
            except ValueError as err:
                return f"accepted, but build_model refused: {str(err)[:200]!r}"
            return "accepted"
    except Hung:
        return f"hung past {LIMIT_S} s"
    except Exception as err:   # noqa: BLE001 - the test reports any other exception
        return f"crashed: {type(err).__name__}: {str(err)[:200]}"
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@pytest.mark.skipif(not hasattr(signal, "SIGALRM"), reason="time limit by SIGALRM")
def test_fuzz_counts(tmp_path):
    tally, failures = {}, []
    for file, data, change in cases():
        result = outcome(tmp_path, file, data)
        kind = result if result in ("rejected", "accepted") else result.split(":")[0]
        tally[kind] = tally.get(kind, 0) + 1
        if result not in ("rejected", "accepted"):
            failures.append(f"{file} ({change}): {result}")
    print(f"\nfuzz of {sum(tally.values())} scene files: {tally}")
    assert not failures, "\n".join(failures)
    assert tally.get("rejected", 0) >= COUNT // 2 and tally.get("accepted", 0) >= 10, tally
