"""Learning the gains of a tendon PID controller for a batch of targets by gradient
descent through the closed-loop rollouts.

    python examples/learn_policy.py [--out out/learn_policy] [--fast]

Set-up: a clamped soft arm (L = 0.2 m, EA = 50 N, EI = 2e-4 N m^2, mass damping 10 1/s)
with one straight tendon at z = 5 mm. The policy is a PID on the tendon tension from the
tip-height error, ``T = kp e + ki int(e) + kd de/dt`` (:func:`simsoft_jax.studies.control.pid`,
the integral carried as the controller's memory), with the reference ramped to the
target over the first 0.5 s. The loss is the mean over a batch of targets of the mean
squared relative tip-height error over the run; its gradient in the log-gains comes from
``jax.vmap`` over the targets of ``simulate(..., control=..., differentiable=True)``
(one program for the batch, implicit derivative at every step) and drives Adam (optax).
The loss keeps falling as the gains grow, until the motion gets too violent for the
steps, even halved: a step into gains whose rollouts fail is undone and the step halved
(counted in the summary).

Printed and saved: the loss and gains at every iteration; for the initial and the
learned gains, a longer run (15 s) per target: its final error and the check that it
ends at the tension of the exact tendon arc (curvature ``T r / EI``, axial strain
``-T / EA``) through its target (the PI steady state); figures
learning_curve.png, responses.png and summary.json (``--fast``: 3 elements, 2 targets,
a shorter run, fewer iterations).
"""
import jax
import jax.numpy as jnp
import matplotlib.pyplot as plt
import numpy as np
import optax

import simsoft_jax as sj
from simsoft_jax.studies import control

from _common import (ARM_EA, ARM_EI, ARM_LENGTH, ARM_OFFSET, parse_args, save, tendon_arm,
                     write_summary)

L, EA, EI, R = ARM_LENGTH, ARM_EA, ARM_EI, ARM_OFFSET   # m, N, N m^2, m
DT, RAMP = 0.05, 0.5                          # s
START_GAINS = (1.0, 1.0, 0.02)                # kp N/m, ki N/(m s), kd N s/m
CHECK_STEPS = 300                             # the learned gains' long run (15 s)


def scene(elements):
    """The arm and its tendon (tension set by the controller)."""
    return {
        "solver": {"kind": "dynamic", "t_end": 1.0, "dt": DT},
        "rods": [tendon_arm(elements)],
        "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}],
        "tendons": [{"name": "t", "rod": "arm", "from_node": 0, "to_node": -1,
                     "offset": [0.0, R], "tension": 0.0}],
    }


def pid_policy(t, state, model, params, integral):
    """PID on the tension: params = (log gains (3,), target height m)."""
    log_gains, height = params
    _, p = control.tip_pose(model, state, "arm")
    linear, _ = control.tip_velocity(model, state, "arm")
    reference = height * jnp.minimum(t / RAMP, 1.0)
    tension, integral = control.pid(control.PIDGains(*jnp.exp(log_gains)), reference - p[2],
                                    -linear[2], integral, DT)
    return model.replace(tendon_tension=model.tendon_tension.at[0].set(tension)), integral


def arc_tension(z):
    """Tension (N) of the exact tendon arc whose tip height is z (bisection)."""
    def height(T):
        k = T * R / EI
        return (1.0 - T / EA) * (1.0 - np.cos(k * L)) / k
    lo, hi = 1e-6, np.pi * EI / (R * L)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if height(mid) < z else (lo, mid)
    return 0.5 * (lo + hi)


def main():
    args = parse_args("learn_policy", __doc__)
    elements, steps, iterations = (3, 60, 5) if args.fast else (6, 80, 30)
    targets = jnp.array([0.025, 0.05] if args.fast else [0.02, 0.035, 0.05, 0.065])
    model = sj.build_model(sj.Scene.from_dict(scene(elements)))
    tip = control.tip_node(model, "arm")
    settings = sj.DynamicSettings(dt=DT, steps=steps, save_every=1)

    def rollout(log_gains, height, differentiable, settings=settings):
        return sj.simulate(model, settings, differentiable=differentiable, control=pid_policy,
                           control_params=(log_gains, height), control_memory=jnp.float64(0.0))

    def loss_one(log_gains, height):
        traj = rollout(log_gains, height, True)
        return jnp.mean(((traj.p[:, tip, 2] - height) / height) ** 2), traj.converged

    def loss_batch(log_gains):
        losses, converged = jax.vmap(loss_one, in_axes=(None, 0))(log_gains, targets)
        return jnp.mean(losses), jnp.all(converged)

    loss_and_grad = jax.jit(jax.value_and_grad(loss_batch, has_aux=True))
    optimizer = optax.adam(0.3)
    log_gains = jnp.log(jnp.array(START_GAINS))
    opt_state = optimizer.init(log_gains)
    losses, history = [], []
    step_scale, rejected, previous = 1.0, 0, None
    for it in range(iterations + 1):
        (loss, converged), grad = loss_and_grad(log_gains)
        if not (bool(converged) and np.all(np.isfinite(np.asarray(grad)))):
            # a closed-loop rollout failed: back to the last accepted gains, half the step
            if previous is None:
                raise RuntimeError(f"the closed-loop rollouts fail at the initial gains "
                                   f"{START_GAINS}")
            rejected, step_scale = rejected + 1, 0.5 * step_scale
            print(f"iteration {it:3d}  a rollout failed at kp, ki, kd = "
                  + ", ".join(f"{g:.4g}" for g in np.exp(np.asarray(log_gains)))
                  + f": step halved to {step_scale:g}")
            log_gains, opt_state, grad = previous
        else:
            losses.append(float(loss))
            history.append(np.exp(np.asarray(log_gains)).tolist())
            print(f"iteration {it:3d}  loss {losses[-1]:.5f}  kp, ki, kd = "
                  + ", ".join(f"{g:.4g}" for g in history[-1]))
        if it < iterations:
            previous = (log_gains, opt_state, grad)
            updates, opt_state = optimizer.update(grad, opt_state)
            log_gains = optax.apply_updates(log_gains, step_scale * updates)

    check = settings.replace(steps=CHECK_STEPS, save_every=2)
    runs = jax.jit(jax.vmap(lambda g, h: rollout(g, h, False, check), in_axes=(None, 0)))
    first, last = (runs(jnp.log(jnp.array(history[i])), targets) for i in (0, -1))
    # the gains kept are those of the last accepted iteration
    gains = history[-1]
    final_errors = (np.asarray(last.p[:, -1, tip, 2]) - np.asarray(targets)).tolist()
    initial_errors = (np.asarray(first.p[:, -1, tip, 2]) - np.asarray(targets)).tolist()
    final_tension = (gains[1] * np.asarray(last.control_memory)).tolist()  # e ~ 0, de/dt ~ 0
    exact_tension = [arc_tension(float(z)) for z in targets]
    summary = {"converged": bool(np.all(np.asarray(last.converged))),
               "targets_m": np.asarray(targets).tolist(), "losses": losses,
               "rejected_steps": rejected,
               "gains_history": history, "final_gains": gains,
               "final_errors_m": final_errors, "initial_gains_final_errors_m": initial_errors,
               "training_horizon_s": steps * DT, "check_run_s": CHECK_STEPS * DT,
               "integral_tension_N": final_tension, "arc_tension_N": exact_tension}
    print("final tip errors (mm):", ", ".join(f"{1e3 * e:.3f}" for e in final_errors))
    print("integral term vs arc tension (N):",
          ", ".join(f"{a:.4f}/{b:.4f}" for a, b in zip(final_tension, exact_tension)))

    fig, ax = plt.subplots(figsize=(5.5, 3.5))
    ax.semilogy(losses, "o-")
    ax.set_xlabel("Adam iteration")
    ax.set_ylabel("loss (mean squared relative error)")
    save(fig, args.out, "learning_curve.png")
    fig, ax = plt.subplots(figsize=(6.5, 4.0))
    colors = plt.colormaps["viridis"](np.linspace(0.0, 0.85, len(targets)))
    for i, color in enumerate(colors):
        ax.plot(first.time[i], 1e3 * first.p[i, :, tip, 2], ":", color=color)
        ax.plot(last.time[i], 1e3 * last.p[i, :, tip, 2], "-", color=color)
        ax.axhline(1e3 * float(targets[i]), color=color, lw=0.6, ls="--")
    ax.axvline(steps * DT, color="k", lw=0.6, label="training horizon")
    ax.legend(fontsize=8)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("tip height (mm)")
    ax.set_title("dotted: initial gains, solid: learned", fontsize=9)
    save(fig, args.out, "responses.png")
    write_summary(args.out, summary)


if __name__ == "__main__":
    main()
