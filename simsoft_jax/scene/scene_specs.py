"""Validated scene data: plain frozen dataclasses (NumPy arrays, no JAX).

Produced by :mod:`simsoft_jax.scene.scene`, consumed by :mod:`simsoft_jax.model.model`. Arrays are
read-only float64; node indices are already resolved to non-negative integers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .key_checks import SpecBase
from .materials import Material
from .sections import Section


@dataclass(frozen=True, eq=False)
class SolverSettings(SpecBase):
    kind: str                         # "static" | "dynamic"
    tolerance: float = 1e-10
    max_iterations: int = 50
    load_steps: int = 10
    level_tolerance: float = 1e-3     # static: tolerance of the intermediate load levels
    max_load_step: float | None = None  # static: largest load increment (None: 1/load_steps)
    t_end: float | None = None
    dt: float | None = None
    rho_inf: float = 0.9
    save_every: int = 1
    inertia: str = "consistent"       # "consistent" | "lumped"
    tangent: str = "closed_form"      # "closed_form" | "autodiff"


@dataclass(frozen=True, eq=False)
class GeometrySpec(SpecBase):
    kind: str                         # "straight" | "arc" | "helix" | "polyline"
    length: float | None = None
    radius: float | None = None
    angle_deg: float | None = None
    pitch: float | None = None
    turns: float | None = None
    points: np.ndarray | None = None  # (P, 3), polyline only

    @property
    def arc_length(self) -> float:
        if self.kind == "straight":
            return float(self.length)
        if self.kind == "arc":
            return float(self.radius * math.radians(self.angle_deg))
        if self.kind == "helix":
            return float(self.turns * math.hypot(2.0 * math.pi * self.radius, self.pitch))
        return float(np.linalg.norm(np.diff(self.points, axis=0), axis=1).sum())


@dataclass(frozen=True, eq=False)
class RodSpec(SpecBase):
    name: str
    material: Material | None         # None only when there is no section (both overrides)
    section: Section | None
    shear_coefficients: tuple[float, float] | None
    stiffness: np.ndarray | None      # (6,) EA, GAy, GAz, GJ, EIy, EIz override, or (6,6)
    inertia: np.ndarray | None        # (6,) rhoA x3, rhoJ, rhoIy, rhoIz override, or (6,6)
    elements: int
    geometry: GeometrySpec
    base_position: np.ndarray         # (3,)
    base_rotation: np.ndarray         # (3, 3), columns = local axes of node 0 in world
    initial_points: np.ndarray | None = None  # (P, 3), base frame; P == nodes: exact
    initial_rotations: np.ndarray | None = None   # (nodes, 3, 3), base frame (P == nodes)
    initial_velocities: np.ndarray | None = None  # (nodes, 6) body [v; w] (a restart)
    segments: tuple | None = None     # SegmentSpec per consecutive piece (None: uniform rod)
    contact_radius: float | None = None   # m, overrides [contact].radius for this rod
    magnetic_moment: np.ndarray | None = None  # (3,) A m per unit length, section frame
    hydraulic_diameter: float | None = None    # m, the diameter fluid loads act on

    @property
    def nodes(self) -> int:
        return self.elements + 1

    def node_fractions(self) -> np.ndarray:
        """Where the nodes sit, as fractions (nodes,) of the arc length (0 at the base, 1
        at the tip): equal elements, or equal within each segment of given ``length``."""
        return node_fractions(self.elements, self.segments)

    def node_arc(self) -> np.ndarray:
        """Arc length (m) of each node along the stress-free shape from the base, (nodes,)."""
        return self.node_fractions() * self.geometry.arc_length


def node_fractions(elements: int, segments=None) -> np.ndarray:
    """Node places as fractions (elements+1,) of the arc length: ``i / elements``, or, when
    the segments give their lengths, equal elements within each segment (the last node
    exactly at 1)."""
    if not segments or segments[0].length is None:
        return np.linspace(0.0, 1.0, elements + 1)
    total = sum(seg.length for seg in segments)
    starts = np.concatenate([[0.0], np.cumsum([seg.length for seg in segments])]) / total
    inner = [start + (end - start) * np.arange(seg.elements) / seg.elements
             for seg, start, end in zip(segments, starts, starts[1:])]
    return np.concatenate([*inner, [1.0]])


@dataclass(frozen=True, eq=False)
class SegmentSpec(SpecBase):
    """A consecutive piece of a rod with its own section (e.g. a catheter's guide and
    leader); unset material falls back to the rod's."""
    elements: int
    material: Material | None
    section: Section | None
    shear_coefficients: tuple[float, float] | None
    stiffness: np.ndarray | None
    inertia: np.ndarray | None
    length: float | None = None       # m of arc length (None: the rod's elements are equal)
    magnetic_moment: np.ndarray | None = None  # (3,) A m per unit length (None: the rod's)


@dataclass(frozen=True, eq=False)
class ConstraintSpec(SpecBase):
    kind: str                         # "clamp" | "pin" | "hinge" | "drive"
    rod: str
    node: int                         # non-negative
    axis: str | None = None           # hinge only: "x" | "y" | "z", the free rotation (local)
    times: np.ndarray | None = None          # (S,)   drive only
    displacement: np.ndarray | None = None   # (S, 3) drive only
    rotation: np.ndarray | None = None       # (S, 3) rotation vectors, drive only
    slides_along: np.ndarray | None = None   # (3,) unit vector, drive only


@dataclass(frozen=True, eq=False)
class ProfileSpec(SpecBase):
    kind: str                         # "constant" | "ramp" | "smoothstep" | "linear" | "table"
    t0: float | None = None
    t1: float | None = None
    rate: float | None = None
    t: np.ndarray | None = None
    scale: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class LoadSpec(SpecBase):
    kind: str                         # "force" | "moment" | "distributed_force"
    rod: str
    node: int | None                  # None for distributed_force and loads inside an element
    vector: np.ndarray                # (3,)
    frame: str                        # "world" (dead) | "local" (follower)
    profile: ProfileSpec
    element: int | None = None        # a load by s between two nodes: its element in the rod
    xi: float | None = None           # and its place there, (s - s_A)/L_e in (0, 1)
    offset: np.ndarray | None = None  # (3,) point of action, section frame (forces at nodes)


@dataclass(frozen=True, eq=False)
class MassSpec(SpecBase):
    """A rigid mass attached to a rod node (``[[masses]]``)."""
    rod: str
    node: int                         # non-negative
    mass: float                       # kg
    offset: np.ndarray                # (3,) centre of mass, section frame, m
    inertia: np.ndarray               # (3, 3) about the centre, section frame, kg m^2


@dataclass(frozen=True, eq=False)
class InitialVelocitySpec(SpecBase):
    rod: str
    linear: np.ndarray                # (3,)
    angular: np.ndarray               # (3,)




@dataclass(frozen=True, eq=False)
class BodySpec(SpecBase):
    """A free rigid body (``[[bodies]]``), a 6-DOF node that rods attach to by joints."""
    name: str
    mass: float                       # kg (0: a massless connector)
    inertia: np.ndarray               # (3, 3) about the body origin, body frame, kg m^2
    position: np.ndarray              # (3,) world, m
    rotation: np.ndarray              # (3, 3) body axes in world coordinates


@dataclass(frozen=True, eq=False)
class JointEnd(SpecBase):
    """One side of a joint: a rod node (``rod``, ``node``) or a body (``body``), with an
    ``offset`` (3,) of the joint point in that side's frame (m)."""
    rod: str | None
    node: int | None                  # non-negative, rods only
    body: str | None
    offset: np.ndarray


@dataclass(frozen=True, eq=False)
class JointSpec(SpecBase):
    """A joint (``[[joints]]``): ``weld`` (full pose, the relative transform at the start
    configuration kept) or ``ball`` (the two joint points coincide)."""
    kind: str
    a: JointEnd
    b: JointEnd


@dataclass(frozen=True, eq=False)
class RoutingSpec(SpecBase):
    """A tendon's path in the section frame (m): ``kind`` "constant" (``y``, ``z``),
    "helix" (``radius``, ``pitch``, ``phase_deg``; ``theta = phase + 2 pi s / pitch``),
    or "table" (``s``, ``ys``, ``zs`` sampled along the rod's arc length s, linear in
    between, held constant outside)."""
    kind: str
    y: float = 0.0
    z: float = 0.0
    radius: float | None = None
    pitch: float | None = None
    phase_deg: float = 0.0
    s: np.ndarray | None = None
    ys: np.ndarray | None = None
    zs: np.ndarray | None = None

    def offsets_at(self, s):
        """Offsets (y, z) (m) and slopes d(y, z)/ds at arc lengths ``s`` (...,) m of the rod:
        two (..., 2) arrays."""
        if self.kind == "constant":
            offset = np.broadcast_to([self.y, self.z], s.shape + (2,))
            return offset, np.zeros_like(offset)
        if self.kind == "helix":
            k = 2.0 * np.pi / self.pitch
            theta = np.deg2rad(self.phase_deg) + k * s
            r = self.radius
            return (np.stack([r * np.cos(theta), r * np.sin(theta)], -1),
                    np.stack([-r * k * np.sin(theta), r * k * np.cos(theta)], -1))
        offset = np.stack([np.interp(s, self.s, self.ys), np.interp(s, self.s, self.zs)], -1)
        if len(self.s) == 1:
            return offset, np.zeros_like(offset)
        # slope of the piece s lies on; zero outside the samples (the offset is held there)
        piece = np.clip(np.searchsorted(self.s, s, side="right") - 1, 0, len(self.s) - 2)
        ds = np.diff(self.s)
        slope = np.stack([np.diff(self.ys)[piece] / ds[piece],
                          np.diff(self.zs)[piece] / ds[piece]], -1)
        inside = (s >= self.s[0]) & (s <= self.s[-1])
        return offset, slope * inside[..., None]


@dataclass(frozen=True, eq=False)
class TendonPart(SpecBase):
    """The stretch of a tendon inside one rod: between its nodes ``first`` and ``last``
    (non-negative, first <= last: the elements first .. last-1), at ``routing`` in that
    rod's section frame."""
    rod: str
    first: int
    last: int
    routing: RoutingSpec


@dataclass(frozen=True, eq=False)
class TendonSpec(SpecBase):
    """A tendon (``[[tendons]]``): its ``parts``, one per rod it passes, in order from
    the start (``from_node``) to the termination (``to_node``); ``crossings``: per weld
    between two consecutive parts, ``(joint index, node of the part before, node of the
    part after)`` (one part and no crossing for a tendon in one rod); exactly one of
    ``tension`` (N) and ``displacement`` (m)."""
    name: str
    parts: tuple
    crossings: tuple
    tension: float | None
    displacement: float | None
    profile: ProfileSpec


@dataclass(frozen=True, eq=False)
class ChamberSpec(SpecBase):
    """A pressure chamber (``[[chambers]]``): ``area`` (m^2), centroid ``offset`` (2,)
    (y, z; m, section frame), ``pressure`` (Pa) scaled by ``profile``."""
    name: str
    rod: str
    from_node: int
    to_node: int
    area: float
    offset: np.ndarray
    pressure: float
    profile: ProfileSpec
