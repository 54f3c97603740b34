"""Scene -> Model: nodal frames, element constants, constraint masks and load tables.

A :class:`Model` is a JAX pytree. Its array fields (reference twists, stiffness, loads,
initial frames...) are traced leaves, so changing their values never recompiles a solver;
its :class:`Structure` (node and element counts, rods, constrained dofs, obstacles...) is
static metadata, and so is which optional parts it holds: a term the scene does not use
(gravity, a kind of load, viscosity, mass damping, friction, moving obstacles, magnetic
or fluid loads) has its part None (:mod:`simsoft_jax.model.parts`), which is part of the pytree
structure, so ``model.gravity is not None`` is a trace-time test and nothing of the term
is traced. Solvers are compiled once per structure and set of parts.

Node numbering: the nodes of all rods are concatenated in scene order; element ``e``
joins nodes ``element_nodes[e]`` and ``element_nodes[e] + 1`` (rods are chains), so every
tangent matrix of a scene is block-tridiagonal with 6x6 blocks.

One model: everything a static or dynamic solve reads lives here (stiffness, inertia,
viscosity, constant loads, time-dependent load channels, drive tables, initial
velocities, gravity). Element mass matrices are computed from ``inertia`` inside the
solvers' trace, so replacing any array of a Model changes the solve and its gradient;
there is no second object to rebuild.
"""
from __future__ import annotations

import dataclasses
import warnings
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..math import geometry as geom
from .actuator_tables import chamber_arrays, tendon_arrays
from .field_tables import fluid_part, magnetic_part
from .joint_layout import layout as joint_layout
from .loads import LoadChannels, TimeLaws, build_channels, build_laws
from .parts import refuse_absent
from ..scene.scene_contact import QUADRATURE_POINTS, contact_tables, motion_profiles
from ..scene.scene_mechanisms import jointed_rods
from ..scene.scene_start import check_start, unheld_rods
from ..scene.sections import inertia_diagonal, stiffness_diagonal, viscosity_diagonal
from ..scene.start_frames import chord_started, initial_frames, world_frames
from ..scene.supports import AXES
from .start_balance import balanced_rotations


class RodInfo(NamedTuple):
    """Where a rod's nodes and elements sit in the model arrays."""
    name: str
    first_node: int
    nodes: int
    first_element: int
    elements: int


@dataclasses.dataclass(frozen=True)
class Structure:
    """Static (hashable) description of a Model: changing it recompiles the solvers."""
    n_nodes: int
    element_nodes: tuple          # node A of each element (node B = A + 1)
    rods: tuple                   # RodInfo per rod
    free: tuple                   # n_nodes*6 bools: True where the dof is free
    coupled_stiffness: bool = False   # Model.stiffness is (E,6,6) (couplings), else (E,6)
    coupled_inertia: bool = False     # Model.inertia is (E,6,6) (off-diagonal), else (E,6)
    inertia_offset: bool = False      # some section's centre of mass is off its axis
                                      # (traces terms.offset_gravity under gravity)
    mass_nodes: tuple = ()        # node of each attached mass ([[masses]])
    offset_load_nodes: tuple = () # node of each world-frame force at an offset point
    inertia_kind: str = "consistent"   # "consistent" | "lumped" element inertia
    drive_nodes: tuple = ()       # node index of each drive
    slide_drives: tuple = ()      # indices (into the drives) of the sliding ones
    bodies: tuple = ()            # (name, node) of each [[bodies]] entry
    coupling_nodes: tuple = ()    # nodes solved in the coupling set: the bodies, then
                                  # rod nodes of joints (simsoft_jax.couplings.mechanisms)
    joints: tuple = ()            # (kind, node a, node b) per joint ("weld" | "ball")
    tendon_names: tuple = ()      # name of each tendon ([[tendons]])
    tendon_elements: tuple = ()   # per tendon, E bools: the elements it passes
    tendon_quadrature: int = 1    # Gauss points per element of the tendon length
    tendon_displaced: tuple = ()  # per tendon: True when displacement-controlled
    chamber_names: tuple = ()     # name of each pressure chamber ([[chambers]])
    chamber_elements: tuple = ()  # per chamber, E bools: the elements it spans
    obstacle_names: tuple = ()    # [[obstacles]] names, in scene order
    obstacle_kinds: tuple = ()    # their kinds (simsoft_jax.physics.obstacles.KINDS); () = no contact
    contact_points: int = 0       # quadrature points per element for contact
    self_contact: bool = False    # rod-rod and self contact ([contact] self; statics)
    contact_pairs: int = 0        # element pairs the rod-rod narrow phase holds
    friction_law: str = "regularized"   # dynamic friction ([contact] friction_law):
                                  # "regularized" | "stick_slip" (anchors in the State)
    settling: tuple = ()          # (rod name, free motions in words) of the rods of a
                                  # static scene that their supports leave free to move
                                  # (held by the solve's settling regularization)

    @property
    def n_elements(self) -> int:
        return len(self.element_nodes)

    def settling_mask(self) -> np.ndarray:
        """(n_nodes,) floats: 1 on the nodes of the rods in ``settling``, else 0."""
        mask = np.zeros(self.n_nodes)
        names = {name for name, _ in self.settling}
        for info in self.rods:
            if info.name in names:
                mask[info.first_node:info.first_node + info.nodes] = 1.0
        return mask

    def free_mask(self):
        """Free-dof mask (n_nodes, 6) as a float64 array (1 free, 0 held)."""
        return jnp.asarray(np.array(self.free, float).reshape(self.n_nodes, 6))

    def identity_nodes(self) -> tuple:
        """Nodes whose six dofs are all held (e.g. a clamped end). Every tangent assembled
        with :func:`~simsoft_jax.physics.assembly.apply_constraints` of :meth:`free_mask` has the
        identity in their rows and columns, which the chain factorization leaves out
        (:func:`simsoft_jax.math.linalg.factorize`). Empty with sliding drives: their
        reduction frees a dof of a held node."""
        if self.slide_drives:
            return ()
        held = ~np.array(self.free, bool).reshape(self.n_nodes, 6).any(axis=1)
        return tuple(int(i) for i in np.flatnonzero(held))

    def rod(self, name: str) -> RodInfo:
        for info in self.rods:
            if info.name == name:
                return info
        raise ValueError(f"rod: unknown rod {name!r} (known: {[r.name for r in self.rods]})")


@dataclasses.dataclass(frozen=True)
class Model:
    """Arrays of a discretized scene (SI units). Shapes: N nodes, E elements, D drives.

    Optional parts (:mod:`simsoft_jax.model.parts`) are None when the scene lacks their term,
    and then not traced: nodal_dead, nodal_follower, distributed_world,
    distributed_local, element_point_dead, element_point_follower (no load of that kind,
    with any time law), gravity (no ``[gravity]``), viscosity (all zero), mass_damping
    (all zero), obstacle_friction (no obstacle with friction > 0), obstacle_shift (no
    moving obstacle), magnetic, fluid. :meth:`replace` refuses a value for a part that
    is None, naming it.

    R0 (N,3,3), p0 (N,3): configuration the solvers start from (columns of R0 are the
    local axes in world coordinates). d0 (E,6): stress-free relative twists (spec S34).
    length (E,): reference element lengths ``|d0_U|`` (S35). stiffness, inertia,
    viscosity (E,6): sectional diagonals ``K``, ``M``, ``Upsilon`` (S28, S29); stiffness
    is (E,6,6), full symmetric matrices, when the scene has couplings
    (``structure.coupled_stiffness``); inertia is (E,6,6), spatial inertias per length
    about the axis with an offset centre of mass
    (:func:`~simsoft_jax.scene.sections.inertia_matrix`), when some section has one
    (``structure.coupled_inertia``).
    mass_damping (E,): mass-proportional damping constant of each element (1/s,
    :mod:`~simsoft_jax.physics.terms.mass_damping`).
    nodal_dead (N,6): world-frame force and moment per node (dead loads).
    nodal_follower (N,6): local-frame force and moment per node (follower loads).
    distributed_world / distributed_local (E,3): force per unit length on each element,
    fixed in space / turning with the section. element_point_dead / element_point_follower
    (E,6): a point force and moment inside each element (placed by arc length between its
    nodes: world / section frame) at ``element_point_xi`` (E,) (spec S38). These hold the
    loads with a constant time law; loads with another time law are ``channels``
    (:class:`~simsoft_jax.model.loads.LoadChannels`, pattern times scale(t)); statics applies
    both at full scale.
    gravity (3,): m/s^2. v0 (N,6): initial nodal body velocities ``[linear; angular]``
    (dynamics). drive_times (D,S), drive_displacement (D,S,3), drive_rotation (D,S,3):
    drive tables (world frame, relative to the start pose); drive_slide (D,3): unit world
    direction along which a drive's node slides (zeros for drives holding all six dofs).
    char_length: length scale (m) that makes moments comparable with forces in norms.
    mass (K,), mass_offset (K,3), mass_inertia (K,3,3): attached masses (kg), their centre
    (m) and inertia about it (kg m^2), section frame of node ``structure.mass_nodes[k]``
    (:mod:`simsoft_jax.physics.terms.masses`). offset_force (L,3) world (N), offset_point (L,3)
    section frame (m): dead forces at offset points of nodes
    ``structure.offset_load_nodes`` (:mod:`simsoft_jax.physics.terms.offset_loads`).
    joint_offset_a, joint_offset_b (J,3): the joint point in the frames of the joint's
    nodes a and b (m); joint_rotation (J,3,3): the relative rotation ``R_a^T R_b`` a weld
    keeps (:mod:`simsoft_jax.physics.terms.joints`). Rigid bodies are nodes after the rods' nodes
    (``structure.bodies``), their mass and inertia attached masses.
    tendon_tension (M,) N, tendon_displacement (M,) m (prescribed length change of a
    displacement-controlled tendon), tendon_offset, tendon_slope (M,E,Q,2): the routing
    ``(y, z)`` (m, section frame) and ``d(y, z)/ds`` at the Q Gauss points of every
    element (zeros where the tendon does not pass, ``structure.tendon_elements``),
    tendon_law (:class:`~simsoft_jax.model.loads.TimeLaws`) the tension time laws
    (:mod:`simsoft_jax.physics.terms.tendons`, :mod:`simsoft_jax.model.actuator_tables`). chamber_pressure
    (C,) Pa, chamber_area (C,) m^2, chamber_offset (C,2) m, chamber_law: pressure
    chambers (:mod:`simsoft_jax.physics.terms.chambers`).
    contact_radius (E,) m and contact_stiffness (E,) N/m^2 per element, obstacles (K,11)
    parameter rows (:mod:`simsoft_jax.physics.obstacles`), obstacle_friction (K,) Coulomb
    coefficients (traced in friction when some obstacle has one > 0), slip_velocity
    () m/s: the contact of :mod:`simsoft_jax.physics.terms.contact` (read only when the structure
    has obstacles); obstacle_shift (K,3) m and obstacle_law
    (:class:`~simsoft_jax.model.loads.TimeLaws`): the obstacles' motions, each moved by
    ``shift * scale(t)`` (:func:`simsoft_jax.model.loads.obstacles_at`); obstacle_velocity (K,3)
    m/s their velocities at the model's time (zeros; set with the rows by
    :func:`simsoft_jax.model.loads.loads_at`, read by the friction); slip_displacement (E,) m:
    the slip scale of static friction (:mod:`simsoft_jax.physics.terms.static_friction`);
    contact_damping () the damping ratio ``zeta`` of the normal contact damping (dynamics,
    (D1) of :mod:`simsoft_jax.physics.terms.contact`; None without it);
    self_exclusion () m: the arclength within which a rod's own elements do not touch
    (rod-rod contact, :mod:`simsoft_jax.couplings.rod_pairs`). friction_anchor (E,S,K,3)
    m: the stick-slip anchors (world) of the contact stations during a dynamic step
    (:func:`simsoft_jax.physics.stick_slip.anchored`; None otherwise, and in a built model).
    magnetic (:class:`~simsoft_jax.physics.terms.magnetic.MagneticPart`), fluid
    (:class:`~simsoft_jax.physics.terms.fluid.FluidPart`): the parts of the registered terms
    (:mod:`simsoft_jax.physics.terms.registry`), None when the scene lacks them.
    """
    structure: Structure
    R0: jax.Array
    p0: jax.Array
    d0: jax.Array
    length: jax.Array
    stiffness: jax.Array
    inertia: jax.Array
    viscosity: jax.Array
    mass_damping: jax.Array
    nodal_dead: jax.Array
    nodal_follower: jax.Array
    distributed_world: jax.Array
    distributed_local: jax.Array
    element_point_dead: jax.Array
    element_point_follower: jax.Array
    element_point_xi: jax.Array
    gravity: jax.Array
    char_length: jax.Array
    channels: LoadChannels
    v0: jax.Array
    drive_times: jax.Array
    drive_displacement: jax.Array
    drive_rotation: jax.Array
    drive_slide: jax.Array
    mass: jax.Array
    mass_offset: jax.Array
    mass_inertia: jax.Array
    offset_force: jax.Array
    offset_point: jax.Array
    joint_offset_a: jax.Array
    joint_offset_b: jax.Array
    joint_rotation: jax.Array
    tendon_tension: jax.Array
    tendon_displacement: jax.Array
    tendon_offset: jax.Array
    tendon_slope: jax.Array
    tendon_law: TimeLaws
    chamber_pressure: jax.Array
    chamber_area: jax.Array
    chamber_offset: jax.Array
    chamber_law: TimeLaws
    contact_radius: jax.Array = None
    contact_stiffness: jax.Array = None
    obstacles: jax.Array = None
    obstacle_friction: jax.Array = None
    slip_velocity: jax.Array = None
    obstacle_shift: jax.Array = None
    obstacle_law: TimeLaws = None
    obstacle_velocity: jax.Array = None
    slip_displacement: jax.Array = None
    contact_damping: jax.Array = None
    self_exclusion: jax.Array = None
    friction_anchor: jax.Array = None
    magnetic: object = None
    fluid: object = None

    def replace(self, **changes) -> "Model":
        """A copy with some arrays replaced (same structure: no recompilation).

        Checked, with a ValueError naming the field: an array keeps its shape (the
        structure fixes it), and a part this model was built without (None: e.g.
        ``gravity`` of a scene without gravity, ``viscosity`` of one without viscosity)
        gets no value (:func:`simsoft_jax.model.parts.refuse_absent`): the solvers compiled for
        the model do not read it; build the model from a scene that has the term. A
        present part replaced by None drops its term (another pytree structure: the
        solvers compile again).
        """
        refuse_absent(self, changes)
        for key, value in changes.items():
            old = getattr(self, key, None)
            if (old is not None and value is not None and hasattr(old, "shape")
                    and np.shape(value) != np.shape(old)):
                raise ValueError(f"Model.replace: {key}: shape {np.shape(value)} differs from "
                                 f"the model's {np.shape(old)} (the structure fixes the "
                                 "shapes; build a new model from the scene)")
        return dataclasses.replace(self, **changes)


jax.tree_util.register_dataclass(
    Model,
    data_fields=[f.name for f in dataclasses.fields(Model) if f.name != "structure"],
    meta_fields=["structure"],
)


def _rod_constants(rod):
    """Stiffness and inertia (6,) diagonals or (6,6) matrices and the viscosity diagonal
    (6,) of a RodSpec or SegmentSpec."""
    K = rod.stiffness if rod.stiffness is not None else stiffness_diagonal(
        rod.section, rod.material, rod.shear_coefficients)
    M = rod.inertia if rod.inertia is not None else inertia_diagonal(rod.section, rod.material)
    V = (viscosity_diagonal(rod.section, rod.material) if rod.section is not None
         else np.zeros(6))
    return np.asarray(K, float), np.asarray(M, float), np.asarray(V, float)


def _split_offset_loads(loads):
    """Scene loads -> (loads for the nodal/channel arrays, world-frame forces at an offset
    point). A follower force at an offset ``c`` becomes the force and the constant moment
    ``c x F`` (section frame), with the same time law; a dead one stays a force at its
    point (:mod:`simsoft_jax.physics.terms.offset_loads`; constant profile only, scene.py)."""
    plain, at_offset = [], []
    for ld in loads:
        if ld.offset is None or not np.any(ld.offset):
            plain.append(ld)
        elif ld.frame == "world":
            at_offset.append(ld)
        else:
            plain += [dataclasses.replace(ld, offset=None),
                      dataclasses.replace(ld, kind="moment", offset=None,
                                          vector=np.cross(ld.offset, ld.vector))]
    return plain, at_offset


def _section_table(pieces):
    """Per-element stiffness or inertia from ``[(K, elements), ...]`` (K (6,) or (6,6)):
    (E,6) of the diagonals when no piece has couplings (a 6x6 matrix that is diagonal
    gives exactly its diagonal, so the uncoupled path is used), else (E,6,6) for every
    element. Returns the table and whether it is coupled (the static flag)."""
    def diagonal_of(K):
        return np.diag(K) if K.ndim == 2 and not np.any(K - np.diag(np.diag(K))) else K

    pieces = [(diagonal_of(K), n) for K, n in pieces]
    coupled = any(K.ndim == 2 for K, _ in pieces)
    if coupled:
        full = [K if K.ndim == 2 else np.diag(K) for K, _ in pieces]
        return np.concatenate([np.tile(K, (n, 1, 1)) for K, (_, n) in zip(full, pieces)]), True
    return np.concatenate([np.tile(K, (n, 1)) for K, n in pieces]), False


def _reference_twists(R, p):
    """``d0_e = log(H_e^-1 H_e+1)`` for consecutive frames (spec S34), (n,6): NumPy
    (:func:`~simsoft_jax.math.geometry.log_se3_np`), no compiled program."""
    R, p = np.asarray(R, float), np.asarray(p, float)
    Rt = np.swapaxes(R[:-1], -1, -2)
    return geom.log_se3_np(Rt @ R[1:], np.einsum("nij,nj->ni", Rt, p[1:] - p[:-1]))


def _unheld(scene, frames, rods) -> dict:
    """``{rod name: words}`` of the rods of a static scene that their own supports do not
    hold against every rigid motion, with the motions left free in words
    (:func:`~simsoft_jax.scene.scene_start.unheld_rods`); ``frames = (R0, p0)`` the start
    frames (N,3,3), (N,3). Those with joints may be held through them (a mechanism left
    free fails the solve, with a status); the others are held by the static solve's
    settling regularization (:func:`simsoft_jax.solvers.statics.newton.settling_force`)."""
    R0, p0 = frames

    def frames_of(rod, nodes):
        first = rods[rod.name].first_node
        return {k: (R0[first + k], p0[first + k]) for k in nodes}

    return unheld_rods(scene.rods, scene.constraints, frames_of)


def _initial_velocities(scene, rods, R0, p0):
    """Nodal body velocities (N,6): the scene's ``[[initial_velocity]]`` rigid motions, and
    the saved velocities of rods restarted from a result (``initial.result``)."""
    v0 = np.zeros((len(p0), 6))
    for iv in scene.initial_velocity:
        info = rods[iv.rod]
        base = p0[info.first_node]
        for i in range(info.first_node, info.first_node + info.nodes):
            v_world = iv.linear + np.cross(iv.angular, p0[i] - base)
            v0[i] = np.concatenate([R0[i].T @ v_world, R0[i].T @ iv.angular])
    for rod in scene.rods:
        if rod.initial_velocities is not None:
            first = rods[rod.name].first_node
            v0[first:first + rod.elements + 1] = rod.initial_velocities
    return v0


def _drive_tables(scene, rods):
    """Drive tables padded to a common width (holding the last row): times (D,S),
    displacement (D,S,3), rotation (D,S,3), slide directions (D,3); node indices and
    the indices of the sliding drives (static)."""
    drives = [c for c in scene.constraints if c.kind == "drive"]
    width = max([1] + [len(c.times) for c in drives])

    def hold_last(values):
        return np.concatenate([values, np.repeat(values[-1:], width - len(values), axis=0)])

    k = len(drives)
    times = np.array([np.concatenate([c.times, c.times[-1] + 1.0 + np.arange(width - len(c.times))])
                      for c in drives]).reshape(k, width)
    disp = np.array([hold_last(c.displacement) for c in drives]).reshape(k, width, 3)
    rot = np.array([hold_last(c.rotation) for c in drives]).reshape(k, width, 3)
    slide = np.zeros((k, 3))
    for j, c in enumerate(drives):
        if c.slides_along is not None:
            e = np.asarray(c.slides_along, float)
            slide[j] = e / np.linalg.norm(e)
    nodes = tuple(rods[c.rod].first_node + c.node for c in drives)
    sliding = tuple(j for j, c in enumerate(drives) if c.slides_along is not None)
    return times, disp, rot, slide, nodes, sliding


def build_model(scene, device: bool = True) -> Model:
    """Discretize a validated :class:`~simsoft_jax.scene.scene.Scene` into a :class:`Model`.

    Loads with a constant time law go into the nodal/distributed arrays, the others into
    ``channels``; the scene's ``[solver].inertia`` chooses the element inertia (static).
    ``device``: the arrays on the default device (one batched transfer); False keeps them
    NumPy float64 arrays, which a compiled program transfers when it is called (cheaper
    for a model solved once, as :func:`simsoft_jax.run` does). The checks of the start
    state (:func:`~simsoft_jax.scene.scene_start.check_start`) run again: a scene made by
    ``Scene.replace`` was not validated.
    """
    check_start(scene)
    rods, elem_nodes = [], []
    R0, p0, d0, K, M, V, C = [], [], [], [], [], [], []
    node_offset = element_offset = 0
    for rod in scene.rods:
        R_ref, p_ref = world_frames(rod)
        R_init, p_init = initial_frames(rod, R_ref, p_ref)
        d0.append(_reference_twists(R_ref, p_ref))
        for piece in (rod.segments or (rod,)):
            Kr, Mr, Vr = _rod_constants(piece)
            K.append((Kr, piece.elements))
            M.append((Mr, piece.elements))
            V.append(np.tile(Vr, (piece.elements, 1)))
            material = getattr(piece, "material", None)
            C.append(np.full(piece.elements, getattr(material, "mass_damping", 0.0)))
        R0.append(R_init)
        p0.append(p_init)
        rods.append(RodInfo(rod.name, node_offset, rod.elements + 1, element_offset,
                            rod.elements))
        elem_nodes.extend(range(node_offset, node_offset + rod.elements))
        node_offset += rod.elements + 1
        element_offset += rod.elements
    by_name = {r.name: r for r in rods}
    R0, p0 = np.concatenate(R0), np.concatenate(p0)
    unheld = _unheld(scene, (R0, p0), by_name) if scene.solver.kind == "static" else {}
    jointed = jointed_rods(getattr(scene, "joints", ()))
    held_by_joints = set(unheld) & jointed
    settling = tuple((name, words) for name, words in unheld.items() if name not in jointed)
    joints = joint_layout(scene, by_name, R0, p0, held_by_joints)
    R0, p0 = np.concatenate([R0, joints.R]), np.concatenate([p0, joints.p])
    n_nodes, n_elements = len(p0), element_offset

    free = np.ones((n_nodes, 6), bool)
    for c in scene.constraints:
        node = by_name[c.rod].first_node + c.node
        free[node, :3] = False
        if c.kind in ("clamp", "drive"):
            free[node, 3:] = False
        elif c.kind == "hinge":  # rotation held except about the local axis
            free[node, 3:] = [axis == c.axis for axis in AXES]

    nodal_dead = np.zeros((n_nodes, 6))
    nodal_follower = np.zeros((n_nodes, 6))
    dist_world = np.zeros((n_elements, 3))
    dist_local = np.zeros((n_elements, 3))
    point_dead, point_follower = np.zeros((n_elements, 6)), np.zeros((n_elements, 6))
    point_xi = np.full(n_elements, 0.5)
    loads, offset_loads = _split_offset_loads(scene.loads)
    constant = [ld for ld in loads if ld.profile.kind == "constant"]
    timed = [ld for ld in loads if ld.profile.kind != "constant"]
    for load in constant:
        info = by_name[load.rod]
        if load.kind == "distributed_force":
            target = dist_world if load.frame == "world" else dist_local
            target[info.first_element:info.first_element + info.elements] += load.vector
            continue
        cols = slice(0, 3) if load.kind == "force" else slice(3, 6)
        if load.element is not None:
            target = point_dead if load.frame == "world" else point_follower
            target[info.first_element + load.element, cols] += load.vector
            continue
        target = nodal_dead if load.frame == "world" else nodal_follower
        target[info.first_node + load.node, cols] += load.vector

    d0 = np.concatenate(d0)
    length = np.linalg.norm(d0[:, :3], axis=1)
    K, coupled = _section_table(K)
    M, coupled_inertia = _section_table(M)
    gravity = None if scene.gravity is None else np.asarray(scene.gravity, float)
    V, C = np.concatenate(V), np.concatenate(C)
    times, disp, rot, slide, drive_nodes, sliding = _drive_tables(scene, by_name)
    masses = tuple(dataclasses.replace(m, node=by_name[m.rod].first_node + m.node)
                   for m in getattr(scene, "masses", ())) + joints.masses
    obstacles = getattr(scene, "obstacles", ())
    self_contact = bool(getattr(scene, "contact", None) and scene.contact.self_contact)
    for load in loads:
        if load.element is not None:
            point_xi[by_name[load.rod].first_element + load.element] = load.xi
    tendons, tendon_data = tendon_arrays(scene, by_name, n_elements)
    chambers, chamber_data = chamber_arrays(scene, by_name, n_elements)
    structure = Structure(
        n_nodes=n_nodes, element_nodes=tuple(elem_nodes), rods=tuple(rods),
        free=tuple(free.ravel().tolist()),
        coupled_stiffness=coupled,
        coupled_inertia=coupled_inertia,
        inertia_offset=coupled_inertia and bool(np.any(M[:, 3:, :3])),
        inertia_kind=getattr(scene.solver, "inertia", "consistent"),
        drive_nodes=drive_nodes, slide_drives=sliding, bodies=joints.bodies,
        coupling_nodes=joints.coupling_nodes,
        joints=joints.joints,
        mass_nodes=tuple(m.node for m in masses),
        offset_load_nodes=tuple(by_name[ld.rod].first_node + ld.node for ld in offset_loads),
        **tendons, **chambers,
        obstacle_names=tuple(o.name for o in obstacles),
        obstacle_kinds=tuple(o.kind for o in obstacles),
        contact_points=(scene.contact.quadrature_points if scene.contact else
                        QUADRATURE_POINTS) if obstacles or self_contact else 0,
        self_contact=self_contact,
        contact_pairs=scene.contact.max_pairs if self_contact else 0,
        friction_law=scene.contact.friction_law if scene.contact else "regularized",
        settling=settling,
    )
    arrays = dict(
        R0=R0, p0=p0, d0=d0, length=length, stiffness=K,
        inertia=M, viscosity=V, mass_damping=C,
        nodal_dead=nodal_dead,
        nodal_follower=nodal_follower, distributed_world=dist_world,
        distributed_local=dist_local, element_point_dead=point_dead,
        element_point_follower=point_follower, element_point_xi=point_xi, gravity=gravity,
        char_length=length.mean(), v0=_initial_velocities(scene, by_name, R0, p0),
        drive_times=times, drive_displacement=disp, drive_rotation=rot, drive_slide=slide,
        mass=[m.mass for m in masses],
        mass_offset=np.reshape([m.offset for m in masses], (-1, 3)),
        mass_inertia=np.reshape([m.inertia for m in masses], (-1, 3, 3)),
        offset_force=np.reshape([ld.vector for ld in offset_loads], (-1, 3)),
        offset_point=np.reshape([ld.offset for ld in offset_loads], (-1, 3)),
        joint_offset_a=joints.offset_a, joint_offset_b=joints.offset_b,
        joint_rotation=joints.rotation, **tendon_data, **chamber_data,
        **contact_tables(scene, K, length))
    at_node = [ld for ld in loads if ld.kind != "distributed_force" and ld.element is None]
    inside = [ld for ld in loads if ld.element is not None]
    spread = [ld for ld in loads if ld.kind == "distributed_force"]
    present = {   # the optional parts the scene has (the others are None: not traced)
        "nodal_dead": any(ld.frame == "world" for ld in at_node),
        "nodal_follower": any(ld.frame == "local" for ld in at_node),
        "distributed_world": any(ld.frame == "world" for ld in spread),
        "distributed_local": any(ld.frame == "local" for ld in spread),
        "element_point_dead": any(ld.frame == "world" for ld in inside),
        "element_point_follower": any(ld.frame == "local" for ld in inside),
        "gravity": scene.gravity is not None,
        "viscosity": bool(np.any(V != 0.0)),
        "mass_damping": bool(np.any(C != 0.0)),
        "obstacle_friction": any(o.friction > 0.0 for o in obstacles),
        "obstacle_shift": any(o.profile is not None for o in obstacles),
    }
    arrays.update({k: None for k, has in present.items() if not has})
    model = Model(structure=structure, channels=build_channels(timed, structure, present),
                  tendon_law=build_laws([t.profile for t in getattr(scene, "tendons", ())]),
                  chamber_law=build_laws([c.profile for c in getattr(scene, "chambers", ())]),
                  obstacle_law=build_laws(motion_profiles(obstacles)),
                  magnetic=magnetic_part(scene), fluid=fluid_part(scene),
                  **{k: None if a is None else np.asarray(a, np.float64)
                     for k, a in arrays.items()})
    model = _balanced_start(scene, model)
    # one batched transfer (a device_put per array costs more than the arrays' numbers)
    return jax.device_put(model) if device else model


def _balanced_start(scene, model: Model) -> Model:
    """``model`` with the start rotations of the rods started from points alone
    (:func:`~simsoft_jax.scene.start_frames.chord_started`) in moment balance, positions
    held (:func:`simsoft_jax.model.start_balance.balanced_rotations`; one compile per
    structure, kept by the persistent cache once a solve has enabled it); the chord frames stay, with a warning, where that Newton solve fails.
    Joint nodes keep their chord frames. The relaxed frames are the model's ``R0``, data
    like given ``initial.rotations``: derivatives with respect to the model's arrays hold
    them fixed."""
    s = model.structure
    relaxed = np.zeros(s.n_nodes, bool)
    for rod, info in zip(scene.rods, s.rods):
        relaxed[info.first_node:info.first_node + info.nodes] = chord_started(rod)
    relaxed[list(s.coupling_nodes)] = False
    if not relaxed.any():
        return model
    balance = balanced_rotations(model, relaxed)
    if not bool(balance.converged):
        warnings.warn("initial: the start rotations of the rods started from points alone "
                      "did not reach moment balance (their chord frames are kept; give "
                      "initial.rotations to choose them)", stacklevel=3)
        return model
    return model.replace(R0=np.asarray(balance.R))
