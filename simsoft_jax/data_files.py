"""Paths of the data files shipped with the package (``simsoft_jax/data``, see its README).

The data live inside the package, so the same call finds them from a clone, from
``PYTHONPATH`` and from an installed copy (they are package data in ``pyproject.toml``).
"""
from __future__ import annotations

from importlib import resources
from pathlib import Path

DATA_SETS = ("princeton", "real/pazy_wing_technion", "real/prepazy_wing_technion",
             "real/minguet_dugundji_composite_cantilever", "real/tdcr_isir_nouredeen")


def data_path(*parts: str) -> Path:
    """The path of a shipped data file or folder, e.g. ``data_path("princeton",
    "model_predictions_tip.csv")``; a name that does not exist raises ``FileNotFoundError``
    listing the data sets."""
    path = Path(str(resources.files("simsoft_jax").joinpath("data", *parts)))
    if not path.exists():
        raise FileNotFoundError(f"simsoft_jax data: no {'/'.join(parts)!r} (data sets: "
                                f"{', '.join(DATA_SETS)})")
    return path
