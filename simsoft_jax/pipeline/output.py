"""Safe result files: the output and figure paths are checked before a solve, files are
written atomically (a temporary file in the same folder, then renamed over the target)
with the permissions of any new file, and JSON, written piece by piece, holds no NaN or
Infinity tokens (non-finite numbers are written as ``null``).

Plain Python + NumPy (no JAX).
"""
from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

SUFFIXES = (".json", ".npz")


def check_figure(path, option: str, suffixes) -> Path:
    """Check before a solve that a figure can be written to ``path``: its suffix is one
    of ``suffixes`` and its folder exists and is writable; a ``ValueError`` starting with
    ``option`` (``--plot``, ``--animate``) otherwise. An existing file is replaced."""
    path = Path(path)
    if path.suffix not in suffixes:
        raise ValueError(f"{option}: unsupported suffix {path.suffix!r} of {str(path)!r} "
                         f"(use {', '.join(suffixes)})")
    _check_folder(path, option)
    return path


def _check_folder(path: Path, option: str) -> None:
    """The folder of ``path`` exists and is writable, and ``path`` is not a folder."""
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise ValueError(f"{option}: folder {str(folder)!r} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ValueError(f"{option}: folder {str(folder)!r} is not writable")
    if path.is_dir():
        raise ValueError(f"{option}: {str(path)!r} is a folder")


def check_output(path, force: bool = False) -> Path:
    """Check that a result can be written to ``path`` before anything is solved.

    Rejected with one ``ValueError`` starting with ``output:``: a suffix other than
    ``.json``/``.npz``, a folder that does not exist or is not writable, and an existing
    file unless ``force`` (then it is replaced, atomically, once the solve is done).
    """
    path = Path(path)
    if path.suffix not in SUFFIXES:
        raise ValueError(f"output: unsupported suffix {path.suffix!r} of {str(path)!r} "
                         "(use .json or .npz)")
    _check_folder(path, "output")
    if path.exists() and not force:
        raise ValueError(f"output: {str(path)!r} exists; pass --force to replace it")
    return path


STREAM_DEPTH = 4     # levels of nesting below which long lists are written item by item
STREAM_ITEMS = 64    # a list with more items than this is written item by item


def write_json(fh, data: dict) -> None:
    """Write ``data`` (JSON types and NumPy arrays) to the text file ``fh`` as strict
    JSON, one line per top-level key, non-finite numbers as null
    (:func:`finite_or_none`). Long lists and arrays (a trajectory's time axis) are
    written item by item, each with JSON's C encoder: neither the text nor the arrays as
    Python lists are ever held whole in memory, and a KeyboardInterrupt stops the
    writing between two items (an indent would use the encoder's pure-Python path, 2-3x
    slower)."""
    fh.write("{")
    for i, (key, value) in enumerate(data.items()):
        fh.write(("," if i else "") + f"\n {json.dumps(key)}: ")
        _write_value(fh, value, 1)
    fh.write("\n}\n")


def _write_value(fh, value: Any, depth: int) -> None:
    """One JSON value (see :func:`write_json`), with the C encoder's separators."""
    if depth < STREAM_DEPTH and isinstance(value, dict):
        fh.write("{")
        for j, (key, item) in enumerate(value.items()):
            fh.write((", " if j else "") + json.dumps(key) + ": ")
            _write_value(fh, item, depth + 1)
        fh.write("}")
    elif depth < STREAM_DEPTH and (
            isinstance(value, list) and len(value) > STREAM_ITEMS
            or isinstance(value, np.ndarray) and value.ndim > 1 and len(value) > 1):
        fh.write("[")
        for j, item in enumerate(value):
            if j:
                fh.write(", ")
            _write_value(fh, item, depth + 1)
        fh.write("]")
    else:
        fh.write(json.dumps(finite_or_none(value)[0], allow_nan=False))


def count_nonfinite(value: Any) -> int:
    """How many NaN or infinite floats ``value`` (arrays, floats, dicts, lists) holds:
    the number :func:`finite_or_none` replaces."""
    if isinstance(value, np.ndarray):
        return int(np.count_nonzero(~np.isfinite(value))) if value.dtype.kind == "f" else 0
    if isinstance(value, float):
        return 0 if math.isfinite(value) else 1
    if isinstance(value, dict):
        return sum(count_nonfinite(item) for item in value.values())
    if isinstance(value, (list, tuple)):
        return sum(count_nonfinite(item) for item in value)
    return 0


def finite_or_none(value: Any) -> tuple[Any, int]:
    """``value`` as plain JSON data with every NaN or infinite float replaced by ``None``,
    and the number of values replaced. Arrays become (nested) lists."""
    if isinstance(value, np.ndarray):
        bad = ~np.isfinite(value)
        if not bad.any():
            return value.tolist(), 0
        out = value.astype(object)
        out[bad] = None
        return out.tolist(), int(bad.sum())
    if isinstance(value, float):
        return (value, 0) if math.isfinite(value) else (None, 1)
    if isinstance(value, dict):
        out, count = {}, 0
        for key, item in value.items():
            out[key], n = finite_or_none(item)
            count += n
        return out, count
    if isinstance(value, (list, tuple)):
        pairs = [finite_or_none(item) for item in value]
        return [v for v, _ in pairs], sum(n for _, n in pairs)
    return value, 0
