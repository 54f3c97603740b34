"""Helpers of the scene readers (plain Python + NumPy, never JAX):
path-carrying checks, rotations, the table-file reader and a small TOML writer.

Every check takes the value and its *key path* (``rods[0].section.width``) and raises
one :class:`ValueError` of the form ``"<path>: <what is wrong>"``.
"""

from __future__ import annotations

import contextvars
import dataclasses
import json
import math
import numbers
import re
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterable, Iterator, Sequence

import numpy as np

from ..math.lie_np import exp_so3 as rodrigues

__all__ = [
    "fail", "join", "index", "describe", "plain", "table", "check_keys", "require",
    "number", "positive", "integer", "string", "choice", "vector", "matrix",
    "rotation_vector", "rotation_matrix", "rodrigues", "proper_rotations", "prefixed",
    "readonly", "short_key", "check_depth", "MAX_DEPTH",
    "SpecBase", "same", "read_table", "toml_document", "FILES_READ", "note_read", "readable",
]

# The files a scene's parsing reads besides the scene file itself (tables, result files),
# collected while a caller sets a list here (:func:`simsoft_jax.model.built_models.scene_of`)
FILES_READ: contextvars.ContextVar = contextvars.ContextVar("files_read", default=None)


def note_read(file: Path) -> None:
    """Add ``file`` to :data:`FILES_READ` when a caller collects them."""
    files = FILES_READ.get()
    if files is not None:
        files.append(Path(file))


def fail(path: str, message: str) -> None:
    """Raise the one error a bad input produces (its text :func:`readable`)."""
    raise ValueError(readable(f"{path}: {message}" if path else message))


MAX_MESSAGE = 2000   # characters of an error message
MAX_WORD = 1000      # a run of more non-blank characters is cut (a name, a number)
WORD_ECHO = 100      # characters kept of such a run
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f\u2028\u2029]")
_LONG_WORD = re.compile(r"\S{%d,}" % (MAX_WORD + 1))


def readable(text: str) -> str:
    """``text`` safe to print as one line: control characters (newline, NUL, escape...)
    written as their escapes (``\\n``, ``\\x00``), every run of more than MAX_WORD
    non-blank characters cut to its first WORD_ECHO + "...", and the whole cut to
    MAX_MESSAGE characters + "..." (a scene cannot print a line of its own, nor
    megabytes of a name)."""
    text = _CONTROL.sub(lambda m: m.group().encode("unicode_escape").decode("ascii"), text)
    text = _LONG_WORD.sub(lambda m: m.group()[:WORD_ECHO] + "...", text)
    return text if len(text) <= MAX_MESSAGE else text[:MAX_MESSAGE] + "..."


MAX_DEPTH = 64       # nesting levels (tables and arrays) a scene may have
MAX_KEY_ECHO = 40    # characters of a key repeated in an error message


def short_key(key: Any) -> str:
    """``key`` as text, cut to its first MAX_KEY_ECHO characters + "..." when longer (an
    error message must stay readable whatever key a file holds)."""
    text = str(key)
    return text if len(text) <= MAX_KEY_ECHO else text[:MAX_KEY_ECHO] + "..."


def join(path: str, key: str) -> str:
    """``join("rods[0]", "section") == "rods[0].section"`` (long keys shortened,
    :func:`short_key`)."""
    key = short_key(key)
    return f"{path}.{key}" if path else key


def check_depth(value: Any, limit: int = MAX_DEPTH) -> None:
    """Reject dicts/lists/tuples nested more than ``limit`` levels deep (checked without
    recursion, so any depth gives this one error instead of a RecursionError)."""
    stack = [(value, 1, "")]
    while stack:
        item, depth, path = stack.pop()
        if isinstance(item, dict):
            children = ((join(path, k), v) for k, v in item.items())
        elif isinstance(item, (list, tuple)):
            children = ((index(path, i), v) for i, v in enumerate(item))
        else:
            continue
        if depth > limit:
            fail(path[:80] + ("..." if len(path) > 80 else ""),
                 f"nested more than {limit} levels deep (tables and arrays); a scene "
                 f"may nest at most {limit}")
        stack.extend((v, depth + 1, p) for p, v in children)


def index(path: str, i: int) -> str:
    return f"{path}[{i}]"


def describe(value: Any) -> str:
    """Short description of a bad value for error messages."""
    text = repr(value)
    if len(text) > 40:
        text = text[:37] + "..."
    return f"{type(value).__name__} {text}"


def plain(value: Any, path: str = "") -> Any:
    """Deep copy ``value`` into plain JSON-like types (dict, list, str, int, float, bool).

    NumPy scalars and arrays (handy when building scenes in Python) become Python
    numbers and lists; tuples become lists.  Anything else is rejected.
    """
    if isinstance(value, dict):
        out = {}
        for key, item in value.items():
            if not isinstance(key, str):
                fail(path, f"keys must be strings, got {describe(key)}")
            out[key] = plain(item, join(path, key))
        return out
    if isinstance(value, (list, tuple, np.ndarray)):
        return [plain(item, index(path, i)) for i, item in enumerate(value)]
    # NumPy scalars first: np.float64 subclasses float and np.str_ subclasses str, and
    # their repr (``np.float64(0.5)``) is not valid TOML
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (np.integer, int)):
        return int(value)
    if isinstance(value, (np.floating, float)):
        return float(value)
    if isinstance(value, str):
        return str(value)
    fail(path, f"unsupported value {describe(value)}")


def table(value: Any, path: str, what: str = "a table") -> dict:
    if not isinstance(value, dict):
        fail(path, f"must be {what}, got {describe(value)}")
    return value


def check_keys(d: dict, path: str, allowed: Sequence[str], required: Iterable[str] = ()) -> None:
    """Reject unknown keys (listing the allowed ones) and missing required keys."""
    for key in d:
        if key not in allowed:
            fail(join(path, key), f"unknown key (allowed: {', '.join(allowed)})")
    for key in required:
        require(d, path, key)


def require(d: dict, path: str, key: str) -> Any:
    if key not in d:
        fail(join(path, key), "required key missing")
    return d[key]


def number(value: Any, path: str) -> float:
    """A finite real number (bool is not a number here)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        fail(path, f"must be a number, got {describe(value)}")
    try:
        out = float(value)
    except OverflowError:   # an int beyond the float range (JSON allows any digits)
        out = math.inf
    if not math.isfinite(out):
        fail(path, f"must be finite, got {short_key(value)}")
    return out


def positive(value: Any, path: str) -> float:
    out = number(value, path)
    if out <= 0.0:
        fail(path, f"must be > 0, got {value}")
    return out


def integer(value: Any, path: str, minimum: int | None = None,
            maximum: int | None = None) -> int:
    """An int (not bool, not float) with optional bounds."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        fail(path, f"must be an integer, got {describe(value)}")
    out = int(value)
    if minimum is not None and out < minimum:
        fail(path, f"must be >= {minimum}, got {short_key(out)}")
    if maximum is not None and out > maximum:
        fail(path, f"must be <= {maximum}, got {short_key(out)}")
    return out


def string(value: Any, path: str) -> str:
    if not isinstance(value, str):
        fail(path, f"must be a string, got {describe(value)}")
    return value


def choice(value: Any, path: str, options: Sequence[str]) -> str:
    out = string(value, path)
    if out not in options:
        fail(path, f"must be one of {', '.join(repr(o) for o in options)}, got {out!r}")
    return out


def _sequence(value: Any, path: str, what: str) -> list:
    if not isinstance(value, (list, tuple)):
        fail(path, f"must be {what}, got {describe(value)}")
    return list(value)


def vector(value: Any, path: str, n: int | None = 3, min_len: int = 0) -> np.ndarray:
    """A list of finite numbers; exactly ``n`` of them unless ``n`` is None."""
    what = f"a list of {n} numbers" if n is not None else "a list of numbers"
    items = _sequence(value, path, what)
    if n is not None and len(items) != n:
        fail(path, f"must have {n} entries, got {len(items)}")
    if len(items) < min_len:
        fail(path, f"must have at least {min_len} entries, got {len(items)}")
    return np.array([number(x, index(path, i)) for i, x in enumerate(items)], dtype=float)


def matrix(value: Any, path: str, cols: int = 3, min_rows: int = 1) -> np.ndarray:
    """A list of rows, each a list of ``cols`` numbers -> array (rows, cols)."""
    rows = _sequence(value, path, f"a list of [{cols} numbers] rows")
    if len(rows) < min_rows:
        fail(path, f"must have at least {min_rows} rows, got {len(rows)}")
    out = np.empty((len(rows), cols))
    for i, row in enumerate(rows):
        out[i] = vector(row, index(path, i), cols)
    return out


MAX_ROTATION = 1e6  # rad: beyond it an angle has no digits left below one turn


def rotation_vector(value: Any, path: str) -> np.ndarray:
    """Rotation vector (radians) from ``[x, y, z]`` or ``{axis = [..], angle_deg = ..}``;
    the angle must be at most MAX_ROTATION."""
    if isinstance(value, dict):
        check_keys(value, path, ("axis", "angle_deg"), required=("axis", "angle_deg"))
        axis = vector(value["axis"], join(path, "axis"))
        norm = float(np.linalg.norm(axis / np.abs(axis).max())) if axis.any() else 0.0
        if norm == 0.0:
            fail(join(path, "axis"), "must not be the zero vector")
        angle = number(value["angle_deg"], join(path, "angle_deg"))
        if abs(math.radians(angle)) > MAX_ROTATION:
            fail(join(path, "angle_deg"), f"must be at most {math.degrees(MAX_ROTATION):.4g} "
                 f"in size, got {angle}")
        return axis / np.abs(axis).max() / norm * math.radians(angle)
    if not isinstance(value, (list, tuple)):
        fail(path, "must be a rotation vector [x, y, z] (radians) or "
                   f"{{axis = [..], angle_deg = ..}}, got {describe(value)}")
    out = vector(value, path)
    if np.abs(out).max() > MAX_ROTATION or np.linalg.norm(out) > MAX_ROTATION:
        fail(path, f"rotation angle (its length) must be at most {MAX_ROTATION:g} rad, got "
             f"components up to {np.abs(out).max():g}")
    return out


def rotation_matrix(value: Any, path: str) -> np.ndarray:
    return rodrigues(rotation_vector(value, path))


def proper_rotations(value: Any, path: str, tol: float = 1e-6) -> np.ndarray:
    """A list of 3x3 rotation matrices (columns = axes) -> array (K, 3, 3).

    Each must be orthonormal with determinant +1 to ``tol`` (max-abs of ``R^T R - I``);
    one off by more than 1e-12 (but within ``tol``) is replaced by its nearest rotation
    (polar factor), so the solvers only ever see rotations.
    """
    items = _sequence(value, path, "a list of 3x3 matrices (rows of 3 numbers)")
    out = np.empty((len(items), 3, 3))
    for i, item in enumerate(items):
        ipath = index(path, i)
        R = matrix(item, ipath, 3)
        if R.shape != (3, 3):
            fail(ipath, f"must be a 3x3 matrix (3 rows of 3 numbers), got {len(R)} rows")
        error = float(np.abs(R.T @ R - np.eye(3)).max())
        det = float(np.linalg.det(R))
        if error > tol or abs(det - 1.0) > tol:
            fail(ipath, f"must be a rotation (orthonormal, det +1, to {tol:g}); "
                 f"max |R^T R - I| = {error:.3g}, det = {det:.6g}")
        if error > 1e-12:
            u, _, vt = np.linalg.svd(R)
            R = u @ vt
        out[i] = R
    return out


_ARG_PREFIX = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*): (.*)$", re.DOTALL)


@contextmanager
def prefixed(path: str, keys: Iterable[str] = ()) -> Iterator[None]:
    """Re-raise a constructor's ValueError with the key path in front.

    Constructors name their argument first (``"width: must be > 0"``); when that
    argument is one of ``keys`` the error becomes ``"<path>.width: must be > 0"``.
    """
    try:
        yield
    except ValueError as err:
        message = str(err)
        match = _ARG_PREFIX.match(message)
        if match and match.group(1) in set(keys):
            raise ValueError(readable(f"{join(path, match.group(1))}: {match.group(2)}")) \
                from None
        raise ValueError(readable(f"{path}: {message}")) from None


def readonly(array: np.ndarray | None) -> np.ndarray | None:
    if array is not None:
        array = np.array(array, dtype=float)
        array.setflags(write=False)
    return array


class SpecBase:
    """Equality for frozen specs that hold NumPy arrays (field by field, exact)."""

    def __eq__(self, other: Any) -> bool:
        return type(self) is type(other) and same(self, other)

    __hash__ = None  # type: ignore[assignment]


def same(a: Any, b: Any) -> bool:
    if dataclasses.is_dataclass(a) and not isinstance(a, type):
        if type(a) is not type(b):
            return False
        return all(same(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return (isinstance(a, np.ndarray) and isinstance(b, np.ndarray)
                and a.shape == b.shape and bool(np.array_equal(a, b)))
    if isinstance(a, (tuple, list)) and isinstance(b, (tuple, list)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    return bool(a == b)


def _float_or_none(text: str) -> float | None:
    try:
        return float(text)
    except ValueError:
        return None


def read_table(value: Any, path: str, base_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    """Two columns (t, scale) separated by whitespace or commas; '#' starts a comment;
    a first non-numeric line is taken as a header."""
    name = string(value, path)
    file = Path(name) if Path(name).is_absolute() else base_dir / name
    try:
        text = file.read_text(encoding="utf-8")
    except OSError as err:
        fail(path, f"cannot read {str(file)!r}: {err.strerror or err}")
    except UnicodeDecodeError as err:
        fail(path, f"{str(file)!r} is not a text file (byte {err.start} is not UTF-8); "
             "a table file holds two columns of numbers (t, scale)")
    note_read(file)
    rows: list[tuple[float, float]] = []
    first = True
    for lineno, line in enumerate(text.splitlines(), start=1):
        fields = [f for f in re.split(r"[\s,]+", line.split("#", 1)[0].strip()) if f]
        if not fields:
            continue
        values = [_float_or_none(f) for f in fields]
        header, first = first and None in values, False
        if header:
            continue
        if len(values) != 2 or not all(v is not None and math.isfinite(v) for v in values):
            fail(path, f"{file.name} line {lineno}: need two finite numbers (t, scale)")
        rows.append((values[0], values[1]))
    if not rows:
        fail(path, f"{file.name}: no data rows")
    data = np.array(rows)
    return data[:, 0], data[:, 1]


# A small TOML writer for what scene dictionaries hold: top-level values, tables,
# arrays of tables; anything nested deeper is written inline.

def _toml_key(key: str) -> str:
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else _toml_string(key)


def _toml_string(text: str) -> str:
    return json.dumps(text, ensure_ascii=False).replace("\x7f", "\\u007f")


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)  # finite (validated); repr round-trips exactly
    if isinstance(value, str):
        return _toml_string(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(v)}"
                                for k, v in value.items()) + " }" if value else "{}"
    raise TypeError(f"cannot write {type(value).__name__} to TOML")


def toml_document(data: dict) -> str:
    def is_table_array(v: Any) -> bool:
        return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)

    lines = [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in data.items()
             if not isinstance(v, dict) and not is_table_array(v)]
    for key, value in data.items():
        if isinstance(value, dict):
            lines += ["", f"[{_toml_key(key)}]"]
            lines += [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in value.items()]
        elif is_table_array(value):
            for item in value:
                lines += ["", f"[[{_toml_key(key)}]]"]
                lines += [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in item.items()]
    return "\n".join(lines).lstrip("\n") + "\n"


def polyline(value: Any, path: str) -> np.ndarray:
    """Points (P,3), P >= 2, no two consecutive points equal."""
    points = matrix(value, path, 3, min_rows=2)
    lengths = np.linalg.norm(np.diff(points, axis=0), axis=1)
    for j, seg in enumerate(lengths):
        if seg == 0.0:
            fail(index(path, j + 1), "repeats the previous point (zero-length segment)")
    return points
