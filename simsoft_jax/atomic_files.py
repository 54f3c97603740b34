"""Files written whole or not at all: a temporary file beside the target, synced and
renamed over it, so that an interrupt, a full disk or a bug never leaves a half-written
result, sweep or cache entry (host side, plain Python)."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Any, Callable


def write_atomic(path, write: Callable[[Any], None], binary: bool = False) -> Path:
    """Call ``write(fh)`` on a temporary file beside ``path``, then rename it to ``path``.

    If ``write`` raises (a full disk, an interrupt, a bug), the temporary file is removed
    and ``path`` keeps its old content (or stays absent); the error propagates. The file
    gets the permissions of any new file, ``0666`` less the umask (as ``open`` gives).
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    try:
        os.chmod(tmp, 0o666 & ~_umask())   # mkstemp makes it owner-only
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




def _umask() -> int:
    """The process's file-creation mask (read by setting it and putting it back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask
