"""The Lie-group generalized-alpha scheme (spec algorithm.md section 4): its settings, the
state it advances, its parameters from rho_inf (S53) and the update formulas (S66).

Unknowns per step: the nodal increments ``w = h Delta q`` (N,6); everything else is
eliminated (spec S66): ``a(w) = (w/h - v_n - (1/2 - beta) h a_n)/(beta h)``,
``v(w) = v_n + (1 - gamma) h a_n + gamma h a(w)``,
``vdot(w) = ((1 - alpha_m) a(w) + alpha_m a_n - alpha_f vdot_n)/(1 - alpha_f)``,
``q_{n+1} = q_n o exp(w)`` (S54).
"""
from __future__ import annotations

import dataclasses
from typing import NamedTuple

import jax

from ...physics.assembly import check_tangent


@dataclasses.dataclass(frozen=True)
class DynamicSettings:
    """Settings of a rollout. Traced (changing them never recompiles): dt (s),
    rho_inf in [0, 1], tolerance (Newton stops when the estimated distance to the
    solution, largest nodal correction with translations / char_length and rotations in
    rad, is below it), max_iterations (Newton iterations per step: only a bound the
    iterations are compared with, so scenes and calls that differ in it share one
    program). Static integers (part of the compiled structure): steps (number of
    time steps), save_every (keep every k-th state),
    max_halvings (sub-stepping depth before a step is declared failed), tangent
    ("closed_form" or "autodiff": how element blocks of the iteration matrix are built;
    same matrix, different speed), globalized (Newton of each step started from the
    guess with the smallest residual and kept from overshooting by a backtracking line
    search on the residual, :func:`~.newton.newton_step`: for slack, nearly
    inextensible rods; it changes the iterations and sub-steps, not a converged step's
    solution; False: started from the extrapolated increment, no line search). Use it
    with damping (``rho_inf`` <= 0.5, or mass or contact damping): whole steps of an
    undamped slack rope at ``rho_inf = 0.9`` can gain energy (the crossing ropes of
    cosseratbench at 50 ms, benchmarks/README.md "Newton on slack ropes"), where the
    sub-steps of the default start happen to keep them bounded."""
    dt: float
    steps: int
    rho_inf: float = 0.9
    save_every: int = 1
    tolerance: float = 1e-10
    max_iterations: int = 25
    max_halvings: int = 6
    tangent: str = "closed_form"
    globalized: bool = False

    def __post_init__(self):
        check_tangent(self.tangent)
        if not isinstance(self.globalized, bool):
            raise ValueError(f"DynamicSettings.globalized: expected True or False, "
                             f"got {self.globalized!r}")

    def replace(self, **changes) -> "DynamicSettings":
        """A copy with some settings changed."""
        return dataclasses.replace(self, **changes)


jax.tree_util.register_dataclass(
    DynamicSettings, data_fields=["dt", "rho_inf", "tolerance", "max_iterations"],
    meta_fields=["steps", "save_every", "max_halvings", "tangent", "globalized"])


class State(NamedTuple):
    """Nodal frames R (N,3,3), p (N,3); body velocities v, accelerations vd and the
    generalized-alpha pseudo-acceleration a (N,6); time t (s); anchor (E,S,K,3) m: the
    stick-slip friction's anchors (:mod:`simsoft_jax.physics.stick_slip`; None without that
    law)."""
    R: jax.Array
    p: jax.Array
    v: jax.Array
    vd: jax.Array
    a: jax.Array
    t: jax.Array
    anchor: jax.Array = None


def alpha_parameters(rho_inf):
    """``(alpha_m, alpha_f, gamma, beta)`` of the generalized-alpha scheme (spec S53)."""
    alpha_m = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0)
    alpha_f = rho_inf / (rho_inf + 1.0)
    gamma = 0.5 + alpha_f - alpha_m
    return alpha_m, alpha_f, gamma, 0.25 * (gamma + 0.5) ** 2


def iteration_factors(rho_inf, h):
    """``beta' = (1 - alpha_m)/(h^2 beta (1 - alpha_f))`` and ``gamma' = gamma/(h beta)``,
    the factors of ``M`` and ``C_t`` in the iteration matrix (spec S61, S66)."""
    alpha_m, alpha_f, gamma, beta = alpha_parameters(rho_inf)
    return (1.0 - alpha_m) / (h * h * beta * (1.0 - alpha_f)), gamma / (h * beta)


def fields(rho_inf, state: State, w, h):
    """``a, v, vdot`` of the new state as functions of the increment ``w`` (spec S66)."""
    alpha_m, alpha_f, gamma, beta = alpha_parameters(rho_inf)
    a1 = (w / h - state.v - (0.5 - beta) * h * state.a) / (beta * h)
    v1 = state.v + (1.0 - gamma) * h * state.a + gamma * h * a1
    vd1 = ((1.0 - alpha_m) * a1 + alpha_m * state.a - alpha_f * state.vd) / (1.0 - alpha_f)
    return a1, v1, vd1
