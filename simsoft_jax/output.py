"""Safe result files: the output path is checked before a solve, files are written
atomically (a temporary file in the same folder, then renamed over the target), and JSON
holds no NaN or Infinity tokens (non-finite numbers are written as ``null``).

Plain Python + NumPy (no JAX).
"""
from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path
from typing import Any, Callable

import numpy as np

SUFFIXES = (".json", ".npz")


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
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise ValueError(f"output: folder {str(folder)!r} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ValueError(f"output: folder {str(folder)!r} is not writable")
    if path.is_dir():
        raise ValueError(f"output: {str(path)!r} is a folder")
    if path.exists() and not force:
        raise ValueError(f"output: {str(path)!r} exists; pass --force to replace it")
    return path


def write_atomic(path, write: Callable[[Any], None], binary: bool = False) -> Path:
    """Call ``write(fh)`` on a temporary file beside ``path``, then rename it to ``path``.

    If ``write`` raises (a full disk, an interrupt, a bug), the temporary file is removed
    and ``path`` keeps its old content (or stays absent); the error propagates.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    try:
        with os.fdopen(fd, "wb" if binary else "w",
                       **({} if binary else {"encoding": "utf-8"})) as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    return path


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
