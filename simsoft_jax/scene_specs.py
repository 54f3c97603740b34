"""Validated scene data: plain frozen dataclasses (NumPy arrays, no JAX).

Produced by :mod:`simsoft_jax.scene`, consumed by :mod:`simsoft_jax.model`. Arrays are
read-only float64; node indices are already resolved to non-negative integers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ._validate import SpecBase
from .materials import Material
from .sections import Section


@dataclass(frozen=True, eq=False)
class SolverSettings(SpecBase):
    kind: str                         # "static" | "dynamic"
    tolerance: float = 1e-10
    max_iterations: int = 50
    load_steps: int = 10
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
    stiffness: np.ndarray | None      # (6,) EA, GAy, GAz, GJ, EIy, EIz override
    inertia: np.ndarray | None        # (6,) rhoA x3, rhoJ, rhoIy, rhoIz override
    elements: int
    geometry: GeometrySpec
    base_position: np.ndarray         # (3,)
    base_rotation: np.ndarray         # (3, 3), columns = local axes of node 0 in world
    initial_points: np.ndarray | None = None  # (P, 3), base frame; P == nodes: exact
    initial_rotations: np.ndarray | None = None   # (nodes, 3, 3), base frame (P == nodes)
    initial_velocities: np.ndarray | None = None  # (nodes, 6) body [v; w] (a restart)
    segments: tuple | None = None     # SegmentSpec per consecutive piece (None: uniform rod)
    contact_radius: float | None = None   # m, overrides [contact].radius for this rod

    @property
    def nodes(self) -> int:
        return self.elements + 1


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


