"""Why a solve ended: status codes shared by statics and dynamics, their messages, and the
``throw=True`` option.

Solvers return integer codes (traced arrays, so they survive ``jit`` and ``vmap``); the
host turns them into words with :func:`describe`. A solve reports two codes: ``status``,
how it ended, and ``cause``, the reason of the last failed Newton solve that led there
(for example a static continuation whose load step fell below the minimum because Newton
kept hitting its iteration limit: status ``STEP_TOO_SMALL``, cause ``MAX_ITERATIONS``).
"""
from __future__ import annotations

import enum

import jax
import numpy as np


class Status(enum.IntEnum):
    """How a solve ended (``int`` values are what the solvers return)."""
    CONVERGED = 0
    MAX_ITERATIONS = 1   # a Newton solve reached its iteration limit
    NONFINITE = 2        # a residual or Newton step was NaN or infinite
    STEP_TOO_SMALL = 3   # the load step (statics) or sub-step (dynamics) fell below its minimum
    OFF_BRANCH = 4       # a nodal rotation increment left the branch of the exponential map
    MAX_ATTEMPTS = 5     # the static continuation used all its attempts (max_attempts)
    NOT_RUN = 6          # no failure recorded (used as a cause when there was none)
    INTERRUPTED = 7      # a dynamic run's host driver stopped on KeyboardInterrupt (Ctrl-C)
    #                      between chunks (a static solve interrupted returns no result)
    CONTACT_UNRESOLVED = 8  # a dynamic step hit an obstacle in less than a few steps' time
    UNRESTRAINED = 9     # a static solve at full load kept moving along a motion that the
    #                      supports leave free and nothing else restrains
    CONTACT_PAIRS = 10   # more rod-rod element pairs in contact reach than max_pairs holds

    @property
    def code(self) -> str:
        """Short name written to result files ("converged", "max_iterations", ...)."""
        return self.name.lower()


_REASONS = {
    Status.CONVERGED: "converged",
    Status.MAX_ITERATIONS: "Newton reached its iteration limit (max_iterations)",
    Status.NONFINITE: "a residual or Newton step was not finite (NaN or infinite: a "
                      "singular tangent, e.g. an unrestrained rigid motion, or an overflow)",
    Status.STEP_TOO_SMALL: "the step was halved below its minimum",
    Status.OFF_BRANCH: "a nodal rotation increment reached pi/2, outside the branch of the "
                       "exponential map the solver stays on",
    Status.MAX_ATTEMPTS: "the continuation used all its attempts (max_attempts)",
    Status.NOT_RUN: "no Newton failure recorded",
    Status.CONTACT_UNRESOLVED: "an impact on an obstacle lasts less than ten steps (contact "
                                "time pi sqrt(rhoA/k) too short for the step: soften the "
                                "contact stiffness or shorten dt)",
    Status.UNRESTRAINED: "at the full loads the rods kept moving along a motion their "
                         "supports leave free, which contact, friction and the loads do "
                         "not restrain",
    Status.CONTACT_PAIRS: "more rod-rod element pairs came within contact reach (or touched "
                          "more nodes) than the narrow phase holds: raise [contact] "
                          "max_pairs",
    Status.INTERRUPTED: "interrupted (KeyboardInterrupt, Ctrl-C); the states computed "
                        "before are kept",
}


def reason(code) -> str:
    """The words for one status code."""
    return _REASONS[Status(int(code))]


def describe(kind: str, status, cause, where: float, residual: float) -> str:
    """One sentence saying how a solve ended and where.

    kind: "static" or "dynamic"; status, cause: :class:`Status` codes; where: the load
    level reached (static, fraction of the loads) or the time of the failed step
    (dynamic, s); residual: the residual norm there (N, moments divided by the model's
    characteristic length; a converged dynamic run has none to give).
    """
    status, cause = Status(int(status)), Status(int(cause))
    if status == Status.CONVERGED:   # a dynamic run has no residual left: every step met it
        return (f"static solve converged (residual {residual:.3g} N)" if kind == "static"
                else "dynamic solve converged at every step")
    place = (f"at load level {where:.6g}" if kind == "static" else f"at t = {where:.6g} s")
    if status == Status.INTERRUPTED:
        return f"{kind} solve stopped {place}: {reason(status)}"
    text = f"{kind} solve failed {place}: {reason(status)}"
    if cause not in (status, Status.NOT_RUN, Status.CONVERGED):
        text += f", after {reason(cause)}"
    return text + f"; residual there {residual:.3g}"


class SolveError(RuntimeError):
    """Raised by solvers called with ``throw=True`` when they do not converge."""


def raise_if_failed(kind: str, converged, status, cause, where, residual):
    """Raise :class:`SolveError` with :func:`describe`'s message unless converged.

    Works on concrete values (eager calls) and, through ``jax.debug.callback``, on traced
    ones (inside ``jit``/``vmap``/``grad``: the error surfaces when the program runs)."""
    def check(converged, status, cause, where, residual):
        converged, status, cause = map(np.asarray, (converged, status, cause))
        where, residual = np.asarray(where), np.asarray(residual)
        bad = np.flatnonzero(~converged.reshape(-1))
        if bad.size:
            i = bad[0]
            raise SolveError(describe(kind, status.reshape(-1)[i], cause.reshape(-1)[i],
                                      float(where.reshape(-1)[i]),
                                      float(residual.reshape(-1)[i])))

    args = (converged, status, cause, where, residual)
    if any(isinstance(x, jax.core.Tracer) for x in args):
        jax.debug.callback(check, *args)
    else:
        check(*args)


@jax.custom_jvp
def poison_gradient(ok, x, inputs):
    """Identity on ``x``; where ``ok`` is False its derivative with respect to every float
    array of ``inputs`` (a pytree, e.g. the model and start state) is NaN: a failed solve
    has no derivative, and a finite one (often exactly zero, since the state is frozen
    at the failure) would be wrong."""
    return x


@poison_gradient.defjvp
def _poison_gradient_jvp(primals, tangents):
    ok, x, _ = primals
    _, tx, t_inputs = tangents
    floats = [t for t in jax.tree_util.tree_leaves(t_inputs)
              if jax.numpy.issubdtype(t.dtype, jax.numpy.floating)]
    total = sum((jax.numpy.sum(t) for t in floats), jax.numpy.zeros((), x.dtype))
    return x, tx + jax.numpy.where(ok, 0.0, jax.numpy.nan) * total
