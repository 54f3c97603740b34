"""Bounded nonlinear least squares for a batch of independent problems, driven from the host.

Each problem b minimises ``0.5 |r_b(u_b)|^2`` over a box ``lower <= u_b <= upper``. One call
``evaluate(U) -> (r (B,n), J (B,n,P), ok (B,))`` (a jitted, vmapped function: every
residual and its Jacobian ``dr/du``, e.g. forward mode through the implicit-function
derivative of a static solve) is made per iteration for the whole batch; problems that have
finished are evaluated again where they stand (their solves are the cheap part of a vmapped
batch, whose while loops run as long as the slowest member's) and keep their state.

Two methods (the gradient is ``g = J^T r`` in both):

* ``"levenberg_marquardt"``: projected Levenberg-Marquardt (Nocedal & Wright 2006, sec.
  10.3, with Marquardt's diagonal scaling): variables at a bound whose gradient pushes
  outward are frozen, the step solves ``(J^T J + lam diag(J^T J)) du = -J^T r`` on the
  others and is projected onto the box; a step that lowers the cost is accepted and ``lam``
  divided by 3, any other (or a failed solve) multiplies ``lam`` by 4.
* ``"lbfgs"``: optax L-BFGS directions (``optax.scale_by_lbfgs``, one state per problem)
  along which a projected backtracking (Armijo) line search halves the step until the cost
  falls (a failed solve counts as no decrease); the first step (empty memory) is the
  Cauchy step of the Gauss-Newton model along the gradient; components pinned at a bound are dropped
  from the direction, and where the rest is no descent direction the projected steepest
  descent is taken.

A problem ends as ``REACHED`` when its ``error(r)`` is at most ``tolerance``; as
``STATIONARY`` when the projected gradient falls below ``gradient_tolerance * |J| |r|``
(a stationary point of the cost above the tolerance: with the box, a point where only
bounds stop the descent), or, with ``cost_tolerance > 0`` (Levenberg-Marquardt), when
the Gauss-Newton model of a step predicts a decrease below ``cost_tolerance`` times the
cost (Moré 1978's relative-reduction test: the cost is as low as the residuals' own
round-off lets one tell); as ``STALLED`` when no step lowers the cost any more (``lam``
above 1e12, or a line search that halved 30 times); ``MAX_STEPS`` after ``max_steps``
iterations; ``SOLVE_FAILED`` when the residual cannot be evaluated at the start point.

With ``subspace`` (Levenberg-Marquardt), a callable ``(U, r, J) -> (B,P,P)`` orthogonal
projectors ``Pi`` re-evaluated at every iterate, the steps are confined to the range of
``Pi`` (e.g. the parameter combinations the data determine): the model uses ``J Pi``, the
step is projected by ``Pi`` and the stopping tests use the gradient ``Pi J^T r``; the
other combinations do not move while they stay outside it (a truncated Gauss-Newton
method, Hansen 1998, "Rank-Deficient and Discrete Ill-Posed Problems", sec. 3.2).
"""
from __future__ import annotations

import enum
from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax


class Outcome(enum.IntEnum):
    """How one problem of :func:`least_squares` ended."""
    RUNNING = -1
    REACHED = 0
    STATIONARY = 1
    STALLED = 2
    MAX_STEPS = 3
    SOLVE_FAILED = 4


class Solution(NamedTuple):
    """Per problem (leading axis B): u (B,P), r (B,n), J (B,n,P) at u, outcome (B,)
    :class:`Outcome` codes, steps (B,) iterations made, evaluations (B,) residual
    evaluations (solves), failed_trials (B,) trial points whose solve failed (rejected),
    gradient_norm (B,) of the projected gradient, active (B,P) bounds active at u."""
    u: np.ndarray
    r: np.ndarray
    J: np.ndarray
    outcome: np.ndarray
    steps: np.ndarray
    evaluations: np.ndarray
    failed_trials: np.ndarray
    gradient_norm: np.ndarray
    active: np.ndarray


def projected_gradient(u, g, lower, upper):
    """``g`` with the components that push ``u`` out of an active bound set to zero."""
    pinned = ((u <= lower) & (g > 0)) | ((u >= upper) & (g < 0))
    return np.where(pinned, 0.0, g), pinned


def _lm_step(J, r, lam, pinned):
    """Levenberg-Marquardt steps (B,P) on the free variables (pinned ones stay)."""
    free = (~pinned).astype(float)
    Jf = J * free[:, None, :]
    A = np.einsum("bni,bnj->bij", Jf, Jf)
    diag = np.einsum("bii->bi", A)
    scale = np.maximum(diag, 1e-12 * np.maximum(diag.max(axis=1, keepdims=True), 1e-300))
    A = A + (lam[:, None] * scale)[:, :, None] * np.eye(A.shape[1])
    A = A + np.eye(A.shape[1]) * (1.0 - free)[:, :, None]   # pinned rows: du = 0
    rhs = -np.einsum("bni,bn->bi", Jf, r)
    return np.linalg.solve(A, rhs[..., None])[..., 0] * free


def _gauss_newton_decrease(J, r, pinned):
    """(B,) the largest decrease of the cost the linear model ``r + J du`` allows over
    the free variables: ``0.5 |r|^2 - min 0.5 |r + J du|^2`` (least squares, rank
    deficient allowed)."""
    out = np.empty(len(r))
    for b in range(len(r)):
        Jf = J[b][:, ~pinned[b]]
        if Jf.shape[1] == 0:
            out[b] = 0.0
            continue
        du = np.linalg.lstsq(Jf, -r[b], rcond=None)[0]
        rest = r[b] + Jf @ du
        out[b] = 0.5 * (r[b] @ r[b] - rest @ rest)
    return out


def least_squares(evaluate: Callable, u0, lower, upper, error: Callable, tolerance: float,
                  method: str = "levenberg_marquardt", max_steps: int = 50,
                  gradient_tolerance: float = 1e-6, cost_tolerance: float = 0.0,
                  subspace: Callable | None = None) -> Solution:
    """Solve the batch of bounded least-squares problems described in the module doc.

    evaluate: ``U (B,P) -> (r (B,n), J (B,n,P), ok (B,))``. u0, lower, upper: (B,P) (the
    start is projected onto the box). error: ``r (B,n) -> (B,)`` the measure compared with
    ``tolerance``. subspace: optional ``(U, r, J) -> (B,P,P)`` projectors confining the
    steps (Levenberg-Marquardt only; module doc). Returns a :class:`Solution`.
    """
    if method not in ("levenberg_marquardt", "lbfgs"):
        raise ValueError(f"method: unknown method {method!r} "
                         "(choose 'levenberg_marquardt' or 'lbfgs')")
    if subspace is not None and method != "levenberg_marquardt":
        raise ValueError("subspace: confined steps need method 'levenberg_marquardt'")
    U = np.clip(np.asarray(u0, float), lower, upper)
    B = U.shape[0]
    r, J, ok = (np.asarray(a) for a in evaluate(U))
    Pi = np.broadcast_to(np.eye(U.shape[1]), (B, U.shape[1], U.shape[1]))
    outcome = np.where(ok, Outcome.RUNNING, Outcome.SOLVE_FAILED).astype(int)
    cost = 0.5 * np.sum(r * r, axis=1)
    steps, evals, failed = np.zeros(B, int), np.ones(B, int), np.zeros(B, int)
    lam = np.full(B, 1e-3)
    lbfgs = _Lbfgs(U) if method == "lbfgs" else None

    def classify():
        """Gradient and projected-gradient norm at U; ends reached and stationary problems."""
        g = np.einsum("bij,bnj,bn->bi", Pi, np.nan_to_num(J), np.nan_to_num(r))
        gp, _ = projected_gradient(U, g, lower, upper)
        gnorm = np.linalg.norm(gp, axis=1)
        running = outcome == Outcome.RUNNING
        outcome[running & (error(r) <= tolerance)] = Outcome.REACHED
        scale = np.linalg.norm(np.nan_to_num(J), axis=(1, 2)) * np.linalg.norm(r, axis=1)
        outcome[(outcome == Outcome.RUNNING) & (gnorm <= gradient_tolerance * scale)] = \
            Outcome.STATIONARY
        return g, gnorm

    def confine():
        """The step projectors at U (identity without ``subspace``)."""
        return Pi if subspace is None or not ok.any() else np.asarray(subspace(U, r, J))

    Pi = confine()
    g, gnorm = classify()
    while np.any(outcome == Outcome.RUNNING):
        running = outcome == Outcome.RUNNING
        if lbfgs is None:
            _, pinned = projected_gradient(U, g, lower, upper)
            Jc = np.einsum("bnj,bji->bni", np.nan_to_num(J), Pi)
            if cost_tolerance > 0.0:
                flat = running & (_gauss_newton_decrease(Jc, np.nan_to_num(r),
                                                         pinned) <= cost_tolerance * cost)
                outcome[flat] = Outcome.STATIONARY
                running &= ~flat
                if not running.any():
                    break
            step = np.einsum("bij,bj->bi", Pi, _lm_step(Jc, np.nan_to_num(r), lam, pinned))
            trial = np.clip(U + step, lower, upper)
            trial = np.where(running[:, None], trial, U)
            tr, tJ, tok = (np.asarray(a) for a in evaluate(trial))
            tcost = 0.5 * np.sum(tr * tr, axis=1)
            accept = running & tok & (tcost < cost)
            lam = np.where(accept, lam / 3.0, np.where(running, lam * 4.0, lam))
            stalled = running & ~accept & (lam > 1e12)
        else:
            trial, tr, tJ, tok, tcost, accept, stalled, n = lbfgs.search(
                evaluate, U, g, np.nan_to_num(J), cost, running, lower, upper)
            evals += running * (n - 1)
        evals += running
        failed += running & ~tok
        steps += running
        U = np.where(accept[:, None], trial, U)
        r = np.where(accept[:, None], tr, r)
        J = np.where(accept[:, None, None], tJ, J)
        cost = np.where(accept, tcost, cost)
        if subspace is not None and accept.any():
            Pi = np.where(accept[:, None, None], confine(), Pi)
        g, gnorm = classify()
        if lbfgs is not None:
            lbfgs.advance(g, U, accept)
        outcome[(outcome == Outcome.RUNNING) & stalled] = Outcome.STALLED
        outcome[(outcome == Outcome.RUNNING) & (steps >= max_steps)] = Outcome.MAX_STEPS
    _, active = projected_gradient(U, g, lower, upper)
    active = active | (U <= lower) | (U >= upper)
    return Solution(U, r, J, outcome, steps, evals, failed, gnorm, active)


class _Lbfgs:
    """optax L-BFGS directions for B problems (vmapped states) and the projected
    backtracking line search of :func:`least_squares`."""

    def __init__(self, U):
        self.opt = optax.scale_by_lbfgs()
        self.state = jax.vmap(self.opt.init)(jnp.asarray(U))
        self.update = jax.jit(jax.vmap(self.opt.update))
        self.direction = None

    def advance(self, g, U, accept):
        """Feed the gradient at the (new) iterates into the L-BFGS memories; problems
        whose step was rejected keep their memory."""
        d, state = self.update(jnp.asarray(g), self.state, jnp.asarray(U))
        keep = lambda new, old: jnp.where(  # noqa: E731
            jnp.reshape(jnp.asarray(accept), (-1,) + (1,) * (new.ndim - 1)), new, old)
        self.state = jax.tree_util.tree_map(keep, state, self.state)
        self.direction = np.where(accept[:, None], -np.asarray(d), self.direction)

    def search(self, evaluate, U, g, J, cost, running, lower, upper):
        if self.direction is None:
            # first step: the memory is empty; the steepest descent step to the minimum of
            # the Gauss-Newton model along it (Cauchy step, length |g|^2 / |J g|^2), so
            # that the step has the units of u whatever their scale
            d, self.state = self.update(jnp.asarray(g), self.state, jnp.asarray(U))
            d = np.asarray(d)
            Jd = np.einsum("bni,bi->bn", J, d)
            step = np.sum(g * d, axis=1) / np.maximum(np.sum(Jd * Jd, axis=1), 1e-300)
            self.direction = -step[:, None] * d
        # variables pinned at a bound do not move; a direction that is then no descent
        # direction is replaced by the projected steepest descent
        gp, pinned = projected_gradient(U, g, lower, upper)
        d = np.where(pinned, 0.0, self.direction)
        descent = np.sum(d * g, axis=1) < 0
        d = np.where(descent[:, None], d, -gp)
        alpha = np.ones(len(U))
        pending = running.copy()
        out = [U.copy(), None, None, np.ones(len(U), bool), cost.copy()]
        accept = np.zeros(len(U), bool)
        n = 0
        for _ in range(30):
            trial = np.where(pending[:, None],
                             np.clip(U + alpha[:, None] * d, lower, upper), U)
            tr, tJ, tok = (np.asarray(a) for a in evaluate(trial))
            n += 1
            tcost = 0.5 * np.sum(tr * tr, axis=1)
            slope = np.sum(g * (trial - U), axis=1)
            good = pending & tok & (tcost <= cost + 1e-4 * slope) & (tcost < cost)
            for k, value in enumerate((trial, tr, tJ, tok, tcost)):
                if out[k] is None:
                    out[k] = np.array(value)
                sel = good if k != 3 else pending
                out[k][sel] = value[sel]
            accept |= good
            pending &= ~good
            alpha = np.where(pending, 0.5 * alpha, alpha)
            if not np.any(pending):
                break
        stalled = pending   # 30 halvings without decrease
        return (*out, accept, stalled, n)
