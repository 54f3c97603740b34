"""The built Model of a scene, kept by the scene's content, and the parsed Scene of a
scene file, kept by the file's content (what :func:`~simsoft_jax.run` reads first at
every call).

:func:`model_of` finds the Model of a scene from a digest of the fields it is built from
(pickled and hashed: ~25 us, ~0.14 ms right after a solve, when the caches are cold,
against 1-4 ms of building). A scene whose every part is immutable (frozen specs, tuples,
read-only NumPy arrays that own their data, flat dicts of numbers and names, as
:func:`~simsoft_jax.load_scene` and :meth:`~simsoft_jax.Scene.from_dict` make them) is
remembered by identity too, so running the same Scene object again skips the digest;
its arrays are checked to be still read-only and its dicts unchanged at each such call.

:func:`scene_of` parses a scene file once per content: the same immutable Scene object
while the bytes of the file and of every file its parsing read (tables, result files)
are unchanged (reading and hashing them: ~20 us against 1-3 ms of parsing and checks).
"""
from __future__ import annotations

import collections
import dataclasses
import hashlib
import pickle
from pathlib import Path, PurePath
from typing import NamedTuple

import jax
import numpy as np

from ..scene.key_checks import FILES_READ
from .model import Model, build_model
from ..scene.scene import Scene, load_scene

# Scene fields no Model depends on: the input as given (``raw``) and its file name
_NOT_BUILT_FROM = ("raw", "source")
_SCALARS = (str, bytes, int, float, complex, bool, type(None), np.generic, PurePath)


class Lru(collections.OrderedDict):
    """A dict that drops its least recently used entries beyond ``size`` (compiled
    programs, built models: a session sweeping many structures must not grow without
    bound)."""

    def __init__(self, size: int = 16):
        super().__init__()
        self.size = size

    def __getitem__(self, key):
        value = super().__getitem__(key)
        self.move_to_end(key)
        return value

    def __setitem__(self, key, value):
        super().__setitem__(key, value)
        self.move_to_end(key)
        while len(self) > self.size:
            self.popitem(last=False)


class _Seen(NamedTuple):
    """An immutable scene met before (held, so its id stays its own), its digest, and
    what could still change it: its arrays (read-only when met) and its flat dicts with
    a copy of each."""
    scene: Scene
    key: bytes
    arrays: list
    dicts: list


_MODELS = Lru(size=8)   # digest -> Model
_SEEN = Lru(size=8)     # id(scene) -> _Seen


def forget_models() -> None:
    """Drop the built models kept by their scenes' content (the next
    :func:`model_of` builds again)."""
    _MODELS.clear()
    _SEEN.clear()


def _built_from(scene: Scene) -> tuple:
    return tuple(getattr(scene, f.name) for f in dataclasses.fields(scene)
                 if f.name not in _NOT_BUILT_FROM)


def _immutable(x, arrays: list, dicts: list) -> bool:
    """Whether ``x`` can only change through the arrays and flat dicts it adds to
    ``arrays`` and ``dicts``: frozen dataclasses, tuples, scalars, read-only arrays owning
    their data (a read-only view of a writable array could change), dicts of scalars."""
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        return (type(x).__dataclass_params__.frozen
                and all(_immutable(getattr(x, f.name), arrays, dicts)
                        for f in dataclasses.fields(x)))
    if isinstance(x, tuple):
        return all(_immutable(y, arrays, dicts) for y in x)
    if isinstance(x, np.ndarray):
        arrays.append(x)
        return x.base is None and not x.flags.writeable and x.dtype != object
    if isinstance(x, dict):
        dicts.append((x, dict(x)))
        return all(isinstance(v, _SCALARS) for v in x.values())
    return isinstance(x, _SCALARS)


def scene_key(scene: Scene) -> bytes | None:
    """A digest of every field of ``scene`` a Model is built from (all but ``raw`` and
    ``source``), or None when it cannot be pickled. An immutable scene met before is
    recognised by identity (module docstring)."""
    seen = _SEEN.get(id(scene))
    if (seen is not None and seen.scene is scene
            and not any(a.flags.writeable for a in seen.arrays)
            and all(d == copy for d, copy in seen.dicts)):
        return seen.key
    fields = _built_from(scene)
    try:   # protocol 4: protocol 5 pickles a read-only array apart from a writable one
        key = hashlib.blake2b(pickle.dumps(fields, protocol=4), digest_size=20).digest()
    except Exception:  # noqa: BLE001 -- an unpicklable scene is simply not kept
        return None
    arrays, dicts = [], []
    if _immutable(fields, arrays, dicts):
        _SEEN[id(scene)] = _Seen(scene, key, arrays, dicts)
    return key


def _read_only(x):
    """``x``, or a read-only copy of it when it is a writable array (which may be the
    scene's own: the caller's array is left as it was)."""
    if isinstance(x, np.ndarray) and x.flags.writeable:
        x = x.copy()
        x.setflags(write=False)
    return x


def model_of(scene: Scene) -> Model:
    """``build_model(scene, device=False)``, built once per scene content: a later call
    with a scene equal in every field a Model is built from (the same object, a reload of
    the same file, or an equal dict) returns the same Model, whose arrays are read-only;
    any changed number, name or flag builds a new one."""
    key = scene_key(scene)
    if key is not None and key in _MODELS:
        return _MODELS[key]
    model = jax.tree_util.tree_map(_read_only, build_model(scene, device=False))
    if key is not None:
        _MODELS[key] = model
    return model


class _Parsed(NamedTuple):
    """A scene file parsed before: its Scene and the files read, with their digests."""
    scene: Scene
    files: tuple


_PARSED = Lru(size=8)   # (resolved path, path as given) -> _Parsed


def _digest(file: Path) -> bytes | None:
    try:
        return hashlib.blake2b(file.read_bytes(), digest_size=20).digest()
    except OSError:
        return None


def scene_of(path) -> Scene:
    """``load_scene(path)``, parsed once per content: the same Scene object while the
    file and every file its parsing read have the bytes they had then (an immutable
    scene only: module docstring); any change parses it again. Errors as
    :func:`~simsoft_jax.load_scene`."""
    key = (Path(path).resolve(), str(path))
    parsed = _PARSED.get(key)
    if parsed is not None and all(_digest(f) == d for f, d in parsed.files):
        return parsed.scene
    read = [Path(path)]
    token = FILES_READ.set(read)
    try:
        digests = [_digest(Path(path))]   # before parsing: a later change parses again
        scene = load_scene(path)
    finally:
        FILES_READ.reset(token)
    digests += [_digest(f) for f in read[1:]]
    if None not in digests and _immutable(_built_from(scene), [], []):
        _PARSED[key] = _Parsed(scene, tuple(zip(read, digests)))
    return scene
