"""Model-predictive control of a tendon-driven arm that touches a floor: receding-horizon
tracking of a moving target by gradients through the rollout.

    python examples/mpc_tendon_tracking.py [--out out/mpc_tendon_tracking] [--fast]

Set-up: a clamped soft arm along x (L = 0.2 m, EA = 50 N, EI = 2e-4 N m^2, mass
damping 10 1/s) with two straight tendons at z = +5 mm ("up") and z = -5 mm ("down"),
above a frictionless floor at z = -20 mm (contact radius 5 mm, so the centreline stays
above -15 mm; penalty stiffness 2e3 N/m^2). The target of the tip height is
``z*(t) = -30 mm sin(2 pi t / P)``, P = 1.6 s: its low part lies below what the floor
lets the tip reach, so the arm is pressed onto the floor there. The run covers one
period (``--fast``: the first half, down onto the floor and back).

Controller: every k steps (dt = 0.02 s) the tensions of the next H steps (two per step,
``T = T_max sigmoid(u)``: between 0 and the actuators' limit T_max = 0.15 N) are optimized with Adam (optax) on the
horizon's mean squared tip-height error plus a small penalty on tension changes, by
``jax.value_and_grad`` through ``simulate(..., control=schedule, differentiable=True)``
(implicit derivative at every step, contact included) from the measured state; the first
k steps are applied to the arm, the plan shifted and warm-started (an optimizer step
whose rollout failed is skipped and counted). The open-loop
reference plays the quasi-static feed-forward: at each step the tension whose exact
tendon arc (curvature ``T r / EI``) puts the tip at the target, ignoring dynamics and
the floor.

Printed and saved: RMS and largest tracking error of both (over the part of the target
above the floor's reach and over the whole run), the wall time of one MPC re-plan
against one open-loop rollout of the whole run; figures tracking.png, tensions.png and
summary.json (``--fast``: 4 elements, shorter run and horizon, fewer Adam steps).
"""
import time

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
FLOOR, RADIUS, AMPLITUDE = -0.02, 0.005, 0.03  # m
PERIOD = 1.6                                    # s
DT, T_MAX, EFFORT = 0.02, 0.15, 1e-2           # s, N, weight of tension changes


def scene(elements):
    """The arm, its two tendons (tension set by the controller) and the floor."""
    tendon = {"rod": "arm", "from_node": 0, "to_node": -1, "tension": 0.0}
    return {
        "solver": {"kind": "dynamic", "t_end": 1.0, "dt": DT},
        "rods": [tendon_arm(elements)],
        "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}],
        "tendons": [dict(tendon, name="up", offset=[0.0, R]),
                    dict(tendon, name="down", offset=[0.0, -R])],
        "obstacles": [{"name": "floor", "kind": "plane", "point": [0.0, 0.0, FLOOR],
                       "normal": [0.0, 0.0, 1.0], "friction": 0.0}],
        "contact": {"radius": RADIUS, "stiffness": 2e3},
    }


def target(t):
    """Tip height to track (m) at times t (s)."""
    return -AMPLITUDE * jnp.sin(2.0 * jnp.pi * t / PERIOD)


def tensions(u):
    """Tendon tensions (N) in (0, T_MAX) from unconstrained parameters u."""
    return T_MAX * jax.nn.sigmoid(u)


def schedule(t, state, model, params):
    """Zero-order hold of a tension table: params = (t0, u (S, 2)); step i after t0
    applies ``tensions(u[i])`` (the last row after the table)."""
    t0, u = params
    i = jnp.clip(jnp.round((t - t0) / DT).astype(int), 0, u.shape[0] - 1)
    return model.replace(tendon_tension=tensions(u[i]))


def feedforward(z):
    """Quasi-static open-loop parameters (S, 2) for tip heights z (S,): the tension of
    the exact tendon arc (curvature ``T r / EI``, axial strain neglected) whose tip
    height is |z|, on the tendon of z's side."""
    z = np.asarray(z, float)
    lo, hi = np.full_like(z, 1e-9), np.full_like(z, np.pi / L)
    for _ in range(100):  # bisection of (1 - cos kL)/k = |z| in the curvature k
        mid = 0.5 * (lo + hi)
        low = (1.0 - np.cos(mid * L)) / mid < np.abs(z)
        lo, hi = np.where(low, mid, lo), np.where(low, hi, mid)
    x = np.clip(EI * 0.5 * (lo + hi) / R / T_MAX, 1e-4, 1.0 - 1e-4)
    u = np.log(x / (1.0 - x))                                  # inverse sigmoid
    off = np.full_like(u, -8.0)
    return np.stack([np.where(z > 0, u, off), np.where(z > 0, off, u)], axis=1)


def main():
    args = parse_args("mpc_tendon_tracking", __doc__)
    elements = 4 if args.fast else 8
    steps = 40 if args.fast else 80                   # run: steps * DT
    every, horizon, iterations = (4, 10, 8) if args.fast else (4, 15, 15)
    model = sj.build_model(sj.Scene.from_dict(scene(elements)))
    tip = control.tip_node(model, "arm")
    plan_settings = sj.DynamicSettings(dt=DT, steps=horizon, save_every=1)
    apply_settings = sj.DynamicSettings(dt=DT, steps=every, save_every=1)

    def horizon_cost(u, t0, state, model):
        traj = sj.simulate(model, plan_settings, state, differentiable=True,
                           control=schedule, control_params=(t0, u))
        error = (traj.p[1:, tip, 2] - target(traj.time[1:])) / AMPLITUDE
        change = jnp.diff(tensions(u), axis=0) / T_MAX
        return jnp.mean(error**2) + EFFORT * jnp.mean(change**2)

    plan_step = jax.jit(jax.value_and_grad(horizon_cost))
    apply = jax.jit(lambda model, state, t0, u: sj.simulate(
        model, apply_settings, state, control=schedule, control_params=(t0, u)))
    optimizer = optax.adam(0.2)

    # open loop: the quasi-static feed-forward over the whole run
    times = np.arange(steps + 1) * DT
    u_open = jnp.asarray(feedforward(target(times)))
    open_settings = sj.DynamicSettings(dt=DT, steps=steps, save_every=1)
    open_run = jax.jit(lambda model, u: sj.simulate(model, open_settings, control=schedule,
                                                    control_params=(0.0, u)))
    opened = jax.block_until_ready(open_run(model, u_open))
    start = time.perf_counter()
    opened = jax.block_until_ready(open_run(model, u_open))
    open_wall = time.perf_counter() - start

    # receding horizon from the start state, warm-started with the feed-forward
    state = sj.initial_state(model)
    u = u_open[:horizon]
    tip_z, applied, plan_walls, final_costs = [float(state.p[tip, 2])], [], [], []
    converged, skipped = True, 0
    for plan in range(steps // every):
        t0 = state.t
        opt_state, last_cost = optimizer.init(u), float("nan")
        start = time.perf_counter()
        for _ in range(iterations):
            cost, grad = plan_step(u, t0, state, model)
            if not (np.isfinite(float(cost)) and bool(jnp.all(jnp.isfinite(grad)))):
                skipped += 1     # a failed horizon rollout: keep the plan as it is
                continue
            last_cost = float(cost)
            updates, opt_state = optimizer.update(grad, opt_state)
            u = optax.apply_updates(u, updates)
        jax.block_until_ready(u)
        plan_walls.append(time.perf_counter() - start)
        final_costs.append(last_cost)
        traj = apply(model, state, t0, u)
        converged &= bool(traj.converged)
        tip_z.extend(np.asarray(traj.p[1:, tip, 2]).tolist())
        applied.extend(np.asarray(tensions(u[:every])).tolist())
        state = traj.final
        # shift the plan by the applied steps; the next horizon starts from the new state
        u = jnp.concatenate([u[every:], jnp.repeat(u[-1:], every, axis=0)])
        u = u.at[-every:].set(jnp.asarray(feedforward(target(
            state.t + DT * np.arange(horizon - every + 1, horizon + 1)))))

    tip_z, applied = np.array(tip_z), np.array(applied)
    z_open = np.asarray(opened.p[:, tip, 2])
    z_target = np.asarray(target(times))
    reach = FLOOR + RADIUS                      # lowest centreline height at the floor
    free = z_target > reach                     # targets the floor leaves reachable
    err_mpc, err_open = tip_z - z_target, z_open - z_target
    rms = lambda e, m=slice(None): float(np.sqrt(np.mean(e[m] ** 2)))  # noqa: E731
    compile_free_plans = plan_walls[1:] or plan_walls
    summary = {
        "converged": converged and bool(opened.converged),
        "steps": steps, "dt_s": DT, "replan_every_steps": every,
        "horizon_steps": horizon, "adam_steps_per_plan": iterations,
        "skipped_adam_steps": skipped,
        "rms_error_mpc_m": rms(err_mpc), "rms_error_open_loop_m": rms(err_open),
        "rms_error_mpc_reachable_m": rms(err_mpc, free),
        "rms_error_open_loop_reachable_m": rms(err_open, free),
        "max_error_mpc_reachable_m": float(np.abs(err_mpc[free]).max()),
        "lowest_tip_mpc_m": float(tip_z.min()), "floor_reach_m": reach,
        "open_loop_rollout_s": open_wall,
        "mpc_plan_s_median": float(np.median(compile_free_plans)),
        "mpc_plan_over_open_loop_rollout": float(np.median(compile_free_plans) / open_wall),
        "mpc_final_horizon_costs": final_costs,
    }
    print(f"tip-height RMS error: MPC {1e3 * summary['rms_error_mpc_m']:.2f} mm, "
          f"open loop {1e3 * summary['rms_error_open_loop_m']:.2f} mm (reachable part: "
          f"{1e3 * summary['rms_error_mpc_reachable_m']:.2f} vs "
          f"{1e3 * summary['rms_error_open_loop_reachable_m']:.2f} mm)")
    print(f"one re-plan ({iterations} gradients of a {horizon}-step rollout): "
          f"{summary['mpc_plan_s_median']:.3f} s; open-loop rollout of all {steps} steps: "
          f"{open_wall:.3f} s (ratio {summary['mpc_plan_over_open_loop_rollout']:.1f})")

    fig, ax = plt.subplots(figsize=(7.0, 4.0))
    ax.plot(times, 1e3 * z_target, "k--", lw=1, label="target")
    ax.plot(times, 1e3 * z_open, color="tab:gray", label="open loop (quasi-static)")
    ax.plot(times[:len(tip_z)], 1e3 * tip_z, color="tab:blue", label="MPC")
    ax.axhline(1e3 * reach, color="tab:brown", lw=0.8, label="floor (centreline limit)")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("tip height (mm)")
    ax.legend(fontsize=8)
    save(fig, args.out, "tracking.png")
    fig, ax = plt.subplots(figsize=(7.0, 3.2))
    t_applied = np.arange(len(applied)) * DT
    ax.step(t_applied, applied[:, 0], where="post", label="up")
    ax.step(t_applied, applied[:, 1], where="post", label="down")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("tension (N)")
    ax.legend(fontsize=8)
    save(fig, args.out, "tensions.png")
    write_summary(args.out, summary)


if __name__ == "__main__":
    main()
