"""Measurements of static scenes, read from CSV for calibration and prediction.

Two layouts. The observation layout (a ``quantity`` column; :func:`read_observations`)
says per row which point (node and offset in the section frame), which quantity
(position, displacement or rotation component, twist), its value and standard deviation,
and optionally the reference case it is relative to. The original position layout
(header required)::

    scene,rod,node,x,y,z
    princeton_0deg,beam,-1,0.5079,,-0.0107

``scene`` is a scene's ``name``; ``rod`` a rod of it; ``node`` the node index within the
rod (0 = first, negative counts from the end as in scene files); ``x, y, z`` the measured
world position (m). An empty cell means "not measured" (e.g. only the deflections
were recorded); every row needs at least one component. Every error names the file,
the line and the column.
"""
from __future__ import annotations

import csv
from pathlib import Path
from typing import NamedTuple, Sequence

import numpy as np

from .calibration import StaticTarget
from ..model.model import build_model
from ..solvers.statics import settings_from_scene

COLUMNS = ("scene", "rod", "node", "x", "y", "z")


def _fail(path: Path, line: int, column: str, message: str):
    raise ValueError(f"measurements: {path.name} line {line}, column {column}: {message}")


def _records(path: Path, columns, required, need: str):
    """``(line, row, node)`` for every data row of the CSV ``path``: the file exists, has
    ``columns`` (``need`` lists them in the error), every row fills the ``required``
    columns and its node is an integer; a file without data rows is an error."""
    if not path.is_file():
        raise ValueError(f"measurements: no such file {str(path)!r}")
    with path.open(newline="") as handle:
        reader = csv.DictReader(handle)
        missing = [c for c in columns if c not in (reader.fieldnames or [])]
        if missing:
            raise ValueError(f"measurements: {path.name} lacks column(s) {missing} ({need})")
        count = 0
        for line, row in enumerate(reader, start=2):
            for key in required:
                if not (row[key] or "").strip():
                    _fail(path, line, key, "empty")
            try:
                node = int(row["node"])
            except ValueError:
                _fail(path, line, "node", f"not an integer: {row['node']!r}")
            count += 1
            yield line, row, node
    if not count:
        raise ValueError(f"measurements: {path.name} has no data rows")


def read_rows(path) -> list[tuple[int, str, str, int, list]]:
    """Parsed rows ``(line, scene, rod, node, [x, y, z] with None for empty)``."""
    path = Path(path)
    rows = []
    for line, row, node in _records(path, COLUMNS, ("scene", "rod", "node"),
                                    f"need {list(COLUMNS)}"):
        xyz = [_number(path, line, row, key, default=None) for key in "xyz"]
        if all(v is None for v in xyz):
            _fail(path, line, "x,y,z", "no component measured")
        rows.append((line, row["scene"].strip(), row["rod"].strip(), node, xyz))
    return rows


def _static_scenes_by_name(scenes: Sequence, purpose: str) -> dict:
    """``{name: scene}`` of validated static scenes; a dynamic scene or a repeated name is
    a ``ValueError`` naming it (``purpose`` says what needs static scenes)."""
    by_name = {}
    for scene in scenes:
        if scene.solver.kind != "static":
            raise ValueError(f"scenes: {scene.name!r} is a {scene.solver.kind} scene; "
                             f"{purpose} needs static scenes")
        if scene.name in by_name:
            raise ValueError(f"scenes: two scenes are named {scene.name!r}; names must be unique")
        by_name[scene.name] = scene
    return by_name


def _global_node(path: Path, line: int, structure, scene_name: str, rod: str, node: int,
                 rod_label: str) -> int:
    """The model-wide index of ``node`` (negative: from the rod's end) of ``rod`` in a
    model ``structure``; an unknown rod or a node out of range fails naming the file and
    line (``rod_label`` names the rod in the node error)."""
    rods = [r.name for r in structure.rods]
    if rod not in rods:
        _fail(path, line, "rod", f"scene {scene_name!r} has no rod {rod!r} (rods: {rods})")
    info = structure.rod(rod)
    if not -info.nodes <= node < info.nodes:
        _fail(path, line, "node", f"{rod_label} has nodes 0..{info.nodes - 1} "
              f"(or -{info.nodes}..-1), got {node}")
    return info.first_node + node % info.nodes


def static_targets(path, scenes: Sequence) -> list[StaticTarget]:
    """One :class:`~simsoft_jax.studies.calibration.StaticTarget` per scene that has measurements,
    with the scene's ``[solver]`` settings (which the fit and :func:`evaluate` honour).

    scenes: validated static :class:`~simsoft_jax.scene.scene.Scene` objects with unique names.
    Raises ``ValueError`` for rows naming unknown scenes, rods or nodes.
    """
    path = Path(path)
    by_name = _static_scenes_by_name(scenes, "calibration from positions")
    models = {}
    collected: dict = {}
    for line, scene_name, rod, node, xyz in read_rows(path):
        if scene_name not in by_name:
            _fail(path, line, "scene", f"unknown scene {scene_name!r} (given: {sorted(by_name)})")
        if scene_name not in models:
            models[scene_name] = build_model(by_name[scene_name])
        global_node = _global_node(path, line, models[scene_name].structure, scene_name,
                                   rod, node, f"rod {rod!r}")
        collected.setdefault(scene_name, []).append((global_node, xyz))
    targets = []
    for name, rows in collected.items():
        nodes = np.array([n for n, _ in rows])
        mask = np.array([[v is not None for v in xyz] for _, xyz in rows])
        values = np.array([[0.0 if v is None else v for v in xyz] for _, xyz in rows])
        targets.append(StaticTarget(models[name], nodes, values, mask,
                                    settings_from_scene(by_name[name].solver)))
    return targets


# ----------------------------------------------------------------------------- observations
OBSERVATION_COLUMNS = ("scene", "rod", "node", "quantity", "value")
OPTIONAL_COLUMNS = ("offset_x", "offset_y", "offset_z", "std", "reference")
QUANTITIES = {"x": ("position", 0), "y": ("position", 1), "z": ("position", 2),
              "ux": ("displacement", 0), "uy": ("displacement", 1),
              "uz": ("displacement", 2), "rx": ("rotation", 0), "ry": ("rotation", 1),
              "rz": ("rotation", 2), "twist": ("rotation", 0), "tilt_x": ("tilt", 0),
              "tilt_y": ("tilt", 1), "tilt_z": ("tilt", 2)}
KINDS = ("position", "displacement", "rotation", "tilt")


class Observation(NamedTuple):
    """One row of an observation file (see :func:`read_observations`); columns: the
    row's other cells ``{column: text}`` (e.g. ``tip_mass``), for splits
    (:meth:`ObservationSet.column`)."""
    line: int
    scene: str
    rod: str
    node: int
    offset: tuple
    quantity: str
    value: float
    std: float
    reference: str | None
    columns: dict = {}


def is_observation_file(path) -> bool:
    """True when the CSV has a ``quantity`` column (the observation layout)."""
    with Path(path).open(newline="") as handle:
        return "quantity" in (csv.DictReader(handle).fieldnames or [])


_REQUIRED = object()


def _number(path, line, row, key, default=_REQUIRED, positive=False):
    """The finite number in ``row[key]`` (``positive``: also > 0); an empty cell gives
    ``default`` (None allowed), or fails when there is none."""
    text = (row.get(key) or "").strip()
    if not text:
        if default is _REQUIRED:
            _fail(path, line, key, "empty")
        return default
    try:
        value = float(text)
    except ValueError:
        _fail(path, line, key, f"not a number: {text!r}")
    if not np.isfinite(value):
        _fail(path, line, key, "not finite")
    if positive and value <= 0.0:
        _fail(path, line, key, f"must be > 0, got {text}")
    return value


def read_observations(path) -> list[Observation]:
    """Rows of an observation CSV (header required; extra columns, e.g. ``tip_mass``,
    are kept per row for splits)::

        scene,rod,node,offset_x,offset_y,offset_z,quantity,value,std,reference
        bend_1.0kg,wing,-1,0.0,0.03,0.0,uz,-0.0811,0.0005,bend_0kg
        tors_1.0kg,wing,-1,,,,twist,0.0523,0.002,tors_0kg

    scene: a scene's ``name``; rod, node (negative from the end) as in scene files;
    offset_x/y/z: the observed point in the node's section frame (m; empty = 0), so
    ``x = p + R offset``. quantity: ``x``, ``y``, ``z`` (world position of the point, m),
    ``ux``, ``uy``, ``uz`` (its displacement, m), ``rx``, ``ry``, ``rz`` (rotation of
    the section, rad: components of ``log(R_ref^T R)``, i.e. about the reference
    section's own axes), ``twist`` (= ``rx``, about the rod axis), ``tilt_x``,
    ``tilt_y``, ``tilt_z`` (change of the angle of the section's x, y or z axis above the
    world x-y plane, rad: ``asin(e_z . R e_k) - asin(e_z . R_ref e_k)``; e.g. a wing's
    twist as a test reads it from the heights of its leading and trailing edges, when
    the chord lies along y and world z is up). value: the measured
    value (m or rad). std: its standard deviation (same unit; empty = 1, unweighted):
    residuals are divided by it. reference: optional name of the scene the row is
    relative to (the same rod and node there, e.g. the unloaded self-weight state):
    displacements and rotations are taken from that scene's equilibrium instead of the
    stress-free start, and a position becomes the difference of the two positions.
    Every error names the file, the line and the column.
    """
    path = Path(path)
    rows = []
    for line, row, node in _records(path, OBSERVATION_COLUMNS,
                                    ("scene", "rod", "node", "quantity"),
                                    f"need {list(OBSERVATION_COLUMNS)}, optional "
                                    f"{list(OPTIONAL_COLUMNS)}"):
        quantity = row["quantity"].strip()
        if quantity not in QUANTITIES:
            _fail(path, line, "quantity", f"unknown quantity {quantity!r} (choose from "
                  f"{', '.join(QUANTITIES)})")
        offset = tuple(_number(path, line, row, f"offset_{a}", 0.0) for a in "xyz")
        reference = (row.get("reference") or "").strip() or None
        extra = {k: (v or "").strip() for k, v in row.items()
                 if k not in OBSERVATION_COLUMNS + OPTIONAL_COLUMNS and k is not None}
        rows.append(Observation(line, row["scene"].strip(), row["rod"].strip(), node,
                                offset, quantity, _number(path, line, row, "value"),
                                _number(path, line, row, "std", 1.0, positive=True),
                                reference, extra))
    return rows


class ObservationSet(NamedTuple):
    """Observation rows resolved against scenes. models: one Model per scene used (rows'
    scenes and references), in ``names`` order; settings: each scene's static solver
    settings (its ``[solver]`` table); per row (n,): model (index), node
    (global node index in its model), ref_model (-1: the model's own start state),
    ref_node, kind (index in :data:`KINDS`), component (0..2), offset (n,3), value,
    std; rows: the :class:`Observation` tuples; path: the file."""
    names: tuple
    models: tuple
    settings: tuple
    model: np.ndarray
    node: np.ndarray
    ref_model: np.ndarray
    ref_node: np.ndarray
    kind: np.ndarray
    component: np.ndarray
    offset: np.ndarray
    value: np.ndarray
    std: np.ndarray
    rows: tuple
    path: str

    def subset(self, keep) -> "ObservationSet":
        """The rows where ``keep`` (n,) is True, with only the scenes they use (their own
        and their references'), so that a fit or a prediction solves only those."""
        keep = np.asarray(keep, bool)
        if keep.shape != self.value.shape:
            raise ValueError(f"keep: must have one entry per row ({len(self.value)}), got "
                             f"shape {keep.shape}")
        arrays = {f: getattr(self, f)[keep] for f in ("model", "node", "ref_model",
                                                        "ref_node", "kind", "component",
                                                        "offset", "value", "std")}
        used = np.union1d(arrays["model"], arrays["ref_model"][arrays["ref_model"] >= 0])
        new = np.full(len(self.models), -1)
        new[used] = np.arange(len(used))
        arrays["model"] = new[arrays["model"]]
        arrays["ref_model"] = np.where(arrays["ref_model"] >= 0,
                                       new[np.maximum(arrays["ref_model"], 0)], -1)
        return self._replace(names=tuple(self.names[i] for i in used),
                             models=tuple(self.models[i] for i in used),
                             settings=tuple(self.settings[i] for i in used),
                             rows=tuple(r for r, k in zip(self.rows, keep) if k), **arrays)

    def column(self, name: str) -> np.ndarray:
        """The values (n,) of a column of the file per row (floats when every cell is a
        number, else strings); ``scene`` and ``quantity`` are columns too. A missing
        column or an empty cell is a ``ValueError`` naming it."""
        if name in ("scene", "quantity", "rod", "reference"):
            return np.array([getattr(r, name) or "" for r in self.rows])
        missing = [r.line for r in self.rows if not r.columns.get(name)]
        if missing:
            known = sorted(self.rows[0].columns) if self.rows else []
            raise ValueError(f"by: {Path(self.path).name} has no value in column {name!r} "
                             f"on line(s) {missing[:5]} (extra columns: {known})")
        cells = [r.columns[name] for r in self.rows]
        try:
            return np.array([float(c) for c in cells])
        except ValueError:
            return np.array(cells)


def observation_set(path, scenes: Sequence, table_map: "TableMap | None" = None) -> ObservationSet:
    """Resolve the rows of ``path`` against validated static ``scenes`` (unique names):
    an observation file (:func:`read_observations`), or with ``table_map`` a data set's
    own table read through it (:func:`read_table`); errors name the file, line and
    column."""
    path = Path(path)
    by_name = _static_scenes_by_name(scenes, "calibration")
    names, models, index = [], [], {}

    def model_of(name, line, column):
        if name not in by_name:
            _fail(path, line, column, f"unknown scene {name!r} (given: {sorted(by_name)})")
        if name not in index:
            index[name] = len(models)
            names.append(name)
            models.append(build_model(by_name[name]))
        return index[name]

    def node_of(m, name, rod, node, line):
        return _global_node(path, line, models[m].structure, name, rod, node,
                            f"rod {rod!r} of scene {name!r}")

    rows = read_observations(path) if table_map is None else read_table(path, table_map)
    cols = {k: [] for k in ("model", "node", "ref_model", "ref_node", "kind", "component")}
    for row in rows:
        m = model_of(row.scene, row.line, "scene")
        cols["model"].append(m)
        cols["node"].append(node_of(m, row.scene, row.rod, row.node, row.line))
        if row.reference is None:
            cols["ref_model"].append(-1)
            cols["ref_node"].append(0)
        else:
            r = model_of(row.reference, row.line, "reference")
            cols["ref_model"].append(r)
            cols["ref_node"].append(node_of(r, row.reference, row.rod, row.node, row.line))
        kind, component = QUANTITIES[row.quantity]
        cols["kind"].append(KINDS.index(kind))
        cols["component"].append(component)
    settings = tuple(settings_from_scene(by_name[n].solver) for n in names)
    return ObservationSet(tuple(names), tuple(models), settings,
                          **{k: np.array(v, int) for k, v in cols.items()},
                          offset=np.array([r.offset for r in rows], float),
                          value=np.array([r.value for r in rows], float),
                          std=np.array([r.std for r in rows], float),
                          rows=tuple(rows), path=str(path))


# ----------------------------------------------------------------------------- native tables
class QuantityColumn(NamedTuple):
    """One measured column of a data set's table: column (its header), quantity (a
    :data:`QUANTITIES` name), scale (the factor to the quantity's SI unit, e.g.
    pi/180 for degrees, 1e-3 for mm, -1 for a column holding -u), std (the measurement
    std in the SI unit; 1 = unweighted), offset (3,) the observed point in the node's
    section frame (m), where ``{column: (values...)}``: read this column only on the
    rows whose cells match (a long table, where a column names what a row measures)."""
    column: str
    quantity: str
    scale: float = 1.0
    std: float = 1.0
    offset: tuple = (0.0, 0.0, 0.0)
    where: dict = {}


class TableMap(NamedTuple):
    """How the rows of a data set's own table become observations (:func:`read_table`):
    scene and reference (None: relative to the stress-free start) are templates filled
    from the row's cells (``"{test}_skin{skin}_{tip_mass_kg:.1f}kg"``: a cell is inserted
    as written, or as a number when a format spec follows the colon); rod and node (in
    the scene, negative from the end) the observed section; quantities the measured
    columns (:class:`QuantityColumn`); where ``{column: (values...)}`` keeps only the rows
    whose cell equals one of the values (numbers compare as numbers); zero_within (a
    template naming a row's loading run, e.g. ``"{test}_{skin}_{load_sequence}"``; None:
    the table is zeroed) subtracts from every reading the same quantity's reading on the
    run's row whose scene is its own reference (the unloaded reading, for a table of
    absolute positions)."""
    scene: str
    rod: str
    node: int
    quantities: tuple
    reference: str | None = None
    where: dict = {}
    zero_within: str | None = None


class _Cell(str):
    """A table cell for a template: as written, or ``float(cell)`` under a format spec."""

    def __format__(self, spec):
        return format(float(self), spec) if spec else str(self)


def _same(cell: str, value) -> bool:
    try:
        return float(cell) == float(value)
    except ValueError:
        return cell == str(value).strip()


def _matches(cells: dict, where: dict) -> bool:
    """True when every ``where`` column's cell equals one of its values."""
    return all(any(_same(cells[c], v) for v in values) for c, values in where.items())


def _fill(path: Path, line: int, template: str, cells: dict, what: str) -> str:
    try:
        return template.format_map(cells)
    except KeyError as err:
        _fail(path, line, str(err.args[0]), f"{what} template {template!r} names a column the "
              f"table does not have (columns: {sorted(cells)})")
    except ValueError:
        _fail(path, line, what, f"template {template!r}: a cell is not a number for its "
              "format spec")


def read_table(path, table_map: TableMap) -> list[Observation]:
    """Observations (:class:`Observation`, as :func:`read_observations` gives them) from a
    data set's own CSV table (e.g. ``tip_mass_sweep_measured.csv`` of the Pazy wing), one
    per row and measured column of ``table_map`` (a column with its own ``where`` only on
    the rows it matches): value = cell x scale (minus the run's unloaded reading with
    ``zero_within``), std, offset, rod, node from the map, scene and reference from its
    templates, every cell of the row kept in ``columns`` (for splits, e.g.
    ``--hold-out-by tip_mass_kg``). An empty cell is "not measured" (skipped); so is a row
    whose scene is its own reference (its relative values vanish by definition). Errors
    name the file, the line and the column."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"measurements: no such file {str(path)!r}")
    for q in table_map.quantities:
        if q.quantity not in QUANTITIES:
            raise ValueError(f"table map: unknown quantity {q.quantity!r} for column "
                             f"{q.column!r} (choose from {', '.join(QUANTITIES)})")
        if not (np.isfinite(q.scale) and np.isfinite(q.std) and q.std > 0):
            raise ValueError(f"table map: column {q.column!r} needs a finite scale and std > 0")
    if table_map.zero_within is not None and table_map.reference is None:
        raise ValueError("table map: zero_within needs a reference template (the run's row "
                         "whose scene is its reference is the zero)")
    with path.open(newline="") as handle:
        reader = csv.DictReader(handle)
        header = reader.fieldnames or []
        needed = ([q.column for q in table_map.quantities] + list(table_map.where)
                  + [c for q in table_map.quantities for c in q.where])
        missing = [c for c in dict.fromkeys(needed) if c not in header]
        if missing:
            raise ValueError(f"measurements: {path.name} lacks column(s) {missing} (the table "
                             f"map reads them; columns: {header})")
        table = [(line, row, {k: _Cell((v or "").strip()) for k, v in row.items()
                              if k is not None})
                 for line, row in enumerate(reader, start=2)]

    def names(line, cells):
        return (_fill(path, line, table_map.scene, cells, "scene"),
                None if table_map.reference is None else
                _fill(path, line, table_map.reference, cells, "reference"))

    def measured(line, row, cells, q):
        return (_number(path, line, row, q.column, default=None)
                if _matches(cells, q.where) else None)

    zeros = {}            # (run, quantity index): (line, the run's unloaded reading)
    if table_map.zero_within is not None:      # every row: a filter may drop the zero's
        for line, row, cells in table:
            scene, reference = names(line, cells)
            if scene != reference:
                continue
            run = _fill(path, line, table_map.zero_within, cells, "zero_within")
            for i, q in enumerate(table_map.quantities):
                value = measured(line, row, cells, q)
                if value is None:
                    continue
                if (run, i) in zeros:
                    _fail(path, line, q.column, f"run {run!r} has a second unloaded reading "
                          f"for {q.quantity} (first on line {zeros[run, i][0]})")
                zeros[run, i] = (line, value)
    rows = []
    for line, row, cells in table:
        if not _matches(cells, table_map.where):
            continue
        scene, reference = names(line, cells)
        if scene == reference:
            continue
        for i, q in enumerate(table_map.quantities):
            value = measured(line, row, cells, q)
            if value is None:
                continue
            if table_map.zero_within is not None:
                run = _fill(path, line, table_map.zero_within, cells, "zero_within")
                if (run, i) not in zeros:
                    _fail(path, line, q.column, f"run {run!r} has no unloaded reading of "
                          f"{q.quantity} (a row whose scene is its reference "
                          f"{reference!r}) to subtract")
                value -= zeros[run, i][1]
            rows.append(Observation(line, scene, table_map.rod, table_map.node,
                                    tuple(map(float, q.offset)), q.quantity,
                                    value * q.scale, float(q.std), reference,
                                    {k: str(v) for k, v in cells.items()}))
    if not rows:
        raise ValueError(f"measurements: {path.name} gives no measured value through the "
                         f"table map (filter {dict(table_map.where)})")
    return rows


TABLE_MAPS = {
    "pazy-tip-sweep": ("real", "pazy_wing_technion", "tip_mass_sweep_map.toml"),
    "prepazy-tip-sweep": ("real", "prepazy_wing_technion", "tip_mass_sweep_map.toml"),
    "minguet-strips": ("real", "minguet_dugundji_composite_cantilever",
                       "displacements_at_x500mm_map.toml"),
    "tdcr-tip-height": ("real", "tdcr_isir_nouredeen", "tip_z_vs_tendon_pull_map.toml"),
}


def load_table_map(source, where: dict | None = None) -> TableMap:
    """A :class:`TableMap` from a TOML file, or a shipped one by name (:data:`TABLE_MAPS`:
    ``"pazy-tip-sweep"``, ``"prepazy-tip-sweep"``, ``"minguet-strips"``,
    ``"tdcr-tip-height"``; each file's comments name the scenes it expects); ``where``
    adds row filters. The file::

        scene = "{test}_skin{skin}_{tip_mass_kg:.1f}kg"   # required template
        reference = "{test}_skin{skin}_0.0kg"             # optional template
        rod = "wing"                                       # required
        node = -1                                          # required
        zero_within = "{test}_{skin}_{load_sequence}"      # optional: the table is not
                                        # zeroed; subtract each run's row whose scene is
                                        # its reference (the unloaded reading)
        [where]                                            # optional filters
        test = ["bending"]
        [[quantities]]                                     # one per measured column
        column = "tip_uz_m"
        quantity = "uz"
        scale = 1.0                    # optional: to SI (m, rad); -1 for a column of -u
        std = 0.0005                   # optional (SI)
        offset = [0.0, -0.006, 0.0]    # optional (m, section frame)
        where = { component = ["u3"] } # optional: only rows whose cells match (a long
                                       # table: one value column, a column naming it)

    Errors name the file and the key."""
    import tomllib
    from ..data_files import data_path
    path = data_path(*TABLE_MAPS[source]) if source in TABLE_MAPS else Path(source)
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, ValueError) as err:
        raise ValueError(f"table map: cannot read {source} ({err}; shipped maps: "
                         f"{', '.join(TABLE_MAPS)})") from None
    where_from = f"table map: {path.name}"
    allowed = ("scene", "reference", "rod", "node", "zero_within", "where", "quantities")
    unknown = set(data) - set(allowed)
    if unknown:
        raise ValueError(f"{where_from}: unknown key {sorted(unknown)[0]!r} (allowed: "
                         f"{', '.join(allowed)})")
    for key, kind in (("scene", str), ("rod", str), ("node", int)):
        if not isinstance(data.get(key), kind):
            raise ValueError(f"{where_from}: {key} must be a {kind.__name__}")
    for key in ("reference", "zero_within"):
        if not isinstance(data.get(key, ""), str):
            raise ValueError(f"{where_from}: {key} must be a string (a template)")
    items = data.get("quantities")
    if not isinstance(items, list) or not items:
        raise ValueError(f"{where_from}: give at least one [[quantities]] (column, quantity)")
    quantities = []
    for i, item in enumerate(items):
        extra = set(item) - set(QuantityColumn._fields)
        if extra or not {"column", "quantity"} <= set(item):
            raise ValueError(f"{where_from}: quantities[{i}] needs column and quantity "
                             f"(optional scale, std, offset, where); got {sorted(item)}")
        offset = item.get("offset", [0.0, 0.0, 0.0])
        if not isinstance(offset, list) or len(offset) != 3:
            raise ValueError(f"{where_from}: quantities[{i}].offset must be [x, y, z]")
        quantities.append(QuantityColumn(item["column"], item["quantity"],
                                         float(item.get("scale", 1.0)),
                                         float(item.get("std", 1.0)), tuple(offset),
                                         _filters(item.get("where", {}), where_from,
                                                  f"quantities[{i}].where")))
    filters = _filters({**data.get("where", {}), **(where or {})}, where_from, "where")
    return TableMap(data["scene"], data["rod"], data["node"], tuple(quantities),
                    data.get("reference"), filters, data.get("zero_within"))


def _filters(table, where_from: str, key: str) -> dict:
    """``{column: (values...)}`` from a TOML table of a value or a list per column."""
    if not isinstance(table, dict):
        raise ValueError(f"{where_from}: {key} must be a table {{column = [values]}}")
    return {k: tuple(v) if isinstance(v, (list, tuple)) else (v,) for k, v in table.items()}
