"""The six-leg parallel continuum robot of examples/six_leg_parallel_robot.py against an
independent shooting solution of the same robot as Cosserat rods (scipy).

Each leg is a Cosserat rod with extension and shear (no distributed load): from its
clamped base (position b, frame R0 with the leg's axis as first column) with the
unknown base force n and moment m0 (world),

    p' = R v,  R' = R [u]x,  v = e1 + C_t^-1 R^T n,  u = C_b^-1 R^T m,
    m(s) = m0 - (p(s) - b) x n  (n is constant),

C_t = diag(EA, GAy, GAz), C_b = diag(GJ, EIy, EIz), integrated over the leg's length L
(scipy.integrate.solve_ivp, DOP853). Unknowns: the six base wrenches and the plate pose
(position c, rotation Q): 42. Equations (Newton, finite-difference Jacobian): each leg's
tip at its attachment point, ``p(L) = c + Q o_j``, with its frame welded, ``R(L) = Q
R0_j`` (the plate starts unrotated, the legs straight), and the plate in equilibrium
under the legs' tip wrenches (-n_j, -m_j(L) at p_j(L)) and the dead force F at leg 0's
attachment. The lengths change from the nominal ones in four increments, each Newton
solve starting from the last.
"""
import sys

import numpy as np
import pytest

from conftest import EXAMPLES_DIR

scipy_integrate = pytest.importorskip("scipy.integrate")
spatial = pytest.importorskip("scipy.spatial.transform")

pytestmark = pytest.mark.slow          # compiles the robot's static solver (~30 s)

sys.path.insert(0, str(EXAMPLES_DIR))
import six_leg_parallel_robot as robot  # noqa: E402

ELEMENTS = 24


def hat(w):
    """Skew matrices of the rows of w (B,3) -> (B,3,3)."""
    z = np.zeros(len(w))
    return np.stack([np.stack([z, -w[:, 2], w[:, 1]], -1),
                     np.stack([w[:, 2], z, -w[:, 0]], -1),
                     np.stack([-w[:, 1], w[:, 0], z], -1)], -2)


def shoot(wrench, base, R0, lengths, Ct, Cb):
    """Tips of B legs from their base wrenches (B,6): positions (B,3), frames (B,3,3) and
    tip moments m(L) (B,3) (world)."""
    B = len(wrench)
    n, m0 = wrench[:, :3], wrench[:, 3:]

    def rhs(_, y):
        y = y.reshape(B, 12)
        p, R = y[:, :3], y[:, 3:].reshape(B, 3, 3)
        m = m0 - np.cross(p - base, n)
        u = np.einsum("bji,bj->bi", R, m) / Cb
        v = np.array([1.0, 0.0, 0.0]) + np.einsum("bji,bj->bi", R, n) / Ct
        dp = np.einsum("bij,bj->bi", R, v)
        dR = R @ hat(u)
        return (lengths[:, None] * np.concatenate([dp, dR.reshape(B, 9)], 1)).ravel()

    y0 = np.concatenate([base, R0.reshape(B, 9)], 1).ravel()
    y = scipy_integrate.solve_ivp(rhs, (0.0, 1.0), y0, method="DOP853", rtol=1e-12,
                                  atol=1e-14).y[:, -1].reshape(B, 12)
    p, R = y[:, :3], y[:, 3:].reshape(B, 3, 3)
    return p, R, m0 - np.cross(p - base, n)


def residual(tips, pose, wrench, offset, R0, force):
    """The 42 equations: 6 x (tip position, tip frame) and the plate's force and moment."""
    p, R, m_tip = tips
    c, Q = pose[:3], spatial.Rotation.from_rotvec(pose[3:]).as_matrix()
    n = wrench[:, :3]
    gap = p - (c + offset @ Q.T)
    turn = spatial.Rotation.from_matrix(np.einsum("bji,bjk->bik", Q @ R0, R)).as_rotvec()
    f = force - n.sum(0)
    arm = p - c
    moment = -(m_tip + np.cross(arm, n)).sum(0) + np.cross(arm[0], force)
    return np.concatenate([gap.ravel(), turn.ravel(), f, moment])


def shooting_robot(base, offset, R0, path, force, Ct, Cb):
    """Plate pose (c (3,), Q (3,3)) at the last leg lengths of ``path``."""
    wrench, pose = np.zeros((6, 6)), np.zeros(6)
    steps = np.array([1e-7] * 3 + [1e-9] * 3)          # N, N m
    for lengths in path:
        for _ in range(30):
            tips = shoot(wrench, base, R0, lengths, Ct, Cb)
            r = residual(tips, pose, wrench, offset, R0, force)
            if np.abs(r[:36]).max() < 1e-13 and np.abs(r[36:]).max() < 1e-10:
                break
            # the legs' columns: each leg's 6 perturbed wrenches, all integrated at once
            W = np.repeat(wrench[None], 6, 0)              # (6 components, 6 legs, 6)
            for k in range(6):
                W[k, :, k] += steps[k]
            moved = shoot(W.reshape(36, 6), np.tile(base, (6, 1)), np.tile(R0, (6, 1, 1)),
                          np.tile(lengths, 6), Ct, Cb)
            J = np.zeros((42, 42))
            for k in range(6):
                for j in range(6):
                    one = [a.copy() for a in tips]
                    for a, b in zip(one, moved):
                        a[j] = b[6 * k + j]
                    w = wrench.copy()
                    w[j, k] += steps[k]
                    J[:, 6 * j + k] = (residual(one, pose, w, offset, R0, force) - r) / steps[k]
            for k in range(6):
                q = pose.copy()
                q[k] += 1e-9
                J[:, 36 + k] = (residual(tips, q, wrench, offset, R0, force) - r) / 1e-9
            dx = np.linalg.solve(J, -r)
            wrench = wrench + dx[:36].reshape(6, 6)
            pose = pose + dx[36:]
        else:
            raise AssertionError(f"shooting did not converge: |r| = {np.abs(r).max()}")
    return pose[:3], spatial.Rotation.from_rotvec(pose[3:]).as_matrix()


def test_forward_kinematics_matches_shooting():
    """Plate pose at the example's leg lengths (plus its force; the plate moves by 8 mm
    and turns by 2.6 deg): simsoft_jax at 24 elements per leg against the shooting
    solution, to 1e-4 of the plate's motion and of its turn. The elements' constant
    strains make the error second order in the element length; measured position and
    rotation errors 1.4e-6 m, 1.5e-5 rad (12 elements), 3.6e-7 m, 3.7e-6 rad (24: 4.5e-5
    and 8.4e-5 of the motion and turn), 8.9e-8 m, 9.4e-7 rad (48)."""
    import simsoft_jax as sj
    from simsoft_jax.solvers import statics

    base, offset, rotvec, nominal = robot.geometry()
    lengths = nominal + np.asarray(robot.DELTAS) * 1e-3
    scene = sj.Scene.from_dict(robot.robot(ELEMENTS, {"kind": "static", "load_steps": 2}))
    model = sj.build_model(scene)
    settings = statics.settings_from_scene(scene.solver)
    actuate = robot.length_actuation(model)
    home = sj.solve_static(actuate(model, nominal), settings)
    eq, _ = robot.follow(model, actuate, settings, home, nominal, lengths)
    assert bool(eq.converged)
    c_model, Q_model = robot.plate_pose(model, eq)

    k = robot.section()[0]
    Ct = np.array([k["EA"], k["GAy"], k["GAz"]])
    Cb = np.array([k["GJ"], k["EIy"], k["EIz"]])
    R0 = spatial.Rotation.from_rotvec(rotvec).as_matrix()
    path = [nominal + x * (lengths - nominal) for x in (0.25, 0.5, 0.75, 1.0)]
    c, Q = shooting_robot(base, offset, R0, path, np.asarray(robot.FORCE), Ct, Cb)

    motion = np.linalg.norm(c - [0.0, 0.0, robot.HEIGHT])
    position_error = np.linalg.norm(c_model - c)
    angle_error = np.linalg.norm(spatial.Rotation.from_matrix(Q.T @ Q_model).as_rotvec())
    angle = np.linalg.norm(spatial.Rotation.from_matrix(Q).as_rotvec())
    print(f"plate moved {motion * 1e3:.4f} mm and turned {np.degrees(angle):.4f} deg; "
          f"simsoft_jax ({ELEMENTS} elements per leg) - shooting: position "
          f"{position_error:.2e} m ({position_error / motion:.1e} of the motion), "
          f"rotation {angle_error:.2e} rad ({angle_error / angle:.1e} of the turn)")
    assert position_error < 1e-4 * motion
    assert angle_error < 1e-4 * angle
