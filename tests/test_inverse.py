"""Inverse statics (:func:`simsoft_jax.solve_inverse`): actuation that reaches targets.

References, independent of the inverse solver: targets made by forward static solves at
known random actuation (so reachable, and the actuation that made them is the one to
recover where it is unique); the closed form of a clamped straight rod under a follower
tip moment M (an arc of curvature M/EI: tip at (sin(kL)/k, (1 - cos(kL))/k), k = M/EI);
targets out of reach (further from the clamp than the rod is long) or needing actuation
outside the bounds, which must be reported unreachable; central differences of solves for
the Jacobian; Rosenbrock's function for the least-squares solver alone.

Robots: a planar one (1 m, 8 elements, EI = 1 N m^2) with follower moments about the
local z axis at the middle and at the tip; a 3-D one (the same rod, EIy = 1.5) with
follower moments about y and z at the middle and at the tip (4 actuators), targets at
both nodes. Every call of a test uses the same batch size, so one program per robot.
"""
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.studies.inverse import node_indices, target_evaluator
from simsoft_jax.solvers.statics import as_traced

TIGHT = sj.StaticSettings(tolerance=1e-12)
NODES = [("arm", 4), ("arm", -1)]   # targets: middle and tip nodes
TOL = 1e-9       # inverse tolerance (fraction of the length) for recovering actuation
REACH = 1e-6     # the requirement: targets reached to 1e-6 of the length


def robot(EIy=1.0, elements=8):
    d = {"name": "inverse_robot", "solver": {"kind": "static"},
         "rods": [{"name": "arm", "elements": elements,
                   "geometry": {"kind": "straight", "length": 1.0},
                   "stiffness": {"EA": 1e3, "GAy": 1e3, "GAz": 1e3, "GJ": 1.0, "EIy": EIy,
                                 "EIz": 1.0},
                   "inertia": {"rhoA": 0.1, "rhoJ": 1e-3, "rhoIy": 1e-3, "rhoIz": 1e-3}}],
         "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}],
         "loads": [{"kind": "moment", "rod": "arm", "node": -1, "vector": [0, 0, 0],
                    "frame": "local"}]}
    return sj.build_model(sj.Scene.from_dict(d))


@pytest.fixture(scope="module")
def planar():
    model = robot()
    return model, sj.leaf_actuation(model, [("nodal_follower", (4, 5)),
                                            ("nodal_follower", (-1, 5))])


@pytest.fixture(scope="module")
def spatial():
    model = robot(EIy=1.5)
    return model, sj.leaf_actuation(model, [("nodal_follower", (4, 4)),
                                            ("nodal_follower", (4, 5)),
                                            ("nodal_follower", (-1, 4)),
                                            ("nodal_follower", (-1, 5))])


def forward(model, actuate, U, nodes):
    """Node positions (B, M, 3) of forward solves at actuation U (B, P)."""
    out = []
    for u in U:
        eq = sj.solve_static(actuate(model, jnp.asarray(u)), TIGHT)
        assert bool(eq.converged)
        out.append(np.asarray(eq.p)[list(node_indices(model, nodes))])
    return np.array(out)


def check_reached(res, U_true, targets, rows):
    assert np.all(res.reached[rows]), res.messages
    np.testing.assert_allclose(res.positions[rows], targets[rows], atol=REACH)
    assert np.all(res.relative_error[rows] <= REACH)
    assert not np.any(res.unreachable[rows] | res.solve_failed[rows])
    # the map from the actuation to the target points is one to one here: same actuation
    np.testing.assert_allclose(res.u[rows], U_true, atol=1e-6)


def test_planar_reachable_closed_form_bounds_and_unreachable(planar):
    """One batch of 6 targets for the planar robot with lower bound 0 on the mid moment:
    3 random reachable ones, the closed-form arc (mid moment 0, at its bound), one made
    with a negative mid moment (outside the bound) and one beyond the rod's reach.
    Targets are the middle and tip nodes (then the actuation reaching them is unique)."""
    model, actuate = planar
    rng = np.random.default_rng(1)
    U = np.column_stack([rng.uniform(0.2, 1.2, 3), rng.uniform(-1.5, 1.5, 3)])
    M = 1.3                                    # closed form: tip moment, EI = 1, L = 1
    arc = np.array([[np.sin(M * s) / M, (1 - np.cos(M * s)) / M, 0.0] for s in (0.5, 1.0)])
    outside = forward(model, actuate, [[-0.8, 0.5]], NODES)[0]
    far = [[0.6, 0.0, 0.0], [1.2, 0.0, 0.0]]
    targets = np.concatenate([forward(model, actuate, U, NODES), arc[None], outside[None],
                              [far]])
    lower, upper = [0.0, -np.inf], [np.inf, np.inf]
    res = sj.solve_inverse(model, actuate, NODES, targets, [0.5, 0.5], lower=lower,
                           upper=upper, tolerance=TOL, settings=TIGHT)
    check_reached(res, U, targets, slice(0, 3))
    assert res.reached[3] and res.relative_error[3] <= REACH
    np.testing.assert_allclose(res.u[3], [0.0, M], atol=1e-6)
    assert np.all(res.u[:, 0] >= 0.0)                        # bounds respected
    for k in (4, 5):
        assert res.unreachable[k] and not res.reached[k], res.messages[k]
        assert res.relative_error[k] > 1e-3
        assert res.messages[k].startswith("unreachable")
    assert res.active[4, 0] and res.u[4, 0] == 0.0           # stopped by the bound
    # beyond reach along the rod: the best is the straight rod (a stationary point by
    # symmetry; bending pulls the tip back), tip 0.2 m short
    assert res.error[5] == pytest.approx(0.2, abs=1e-6)
    np.testing.assert_allclose(res.u[5], 0.0, atol=1e-5)

    # the Jacobian the solver used (forward mode through the IFT derivative of the
    # solves) against central differences of solves, at the start point of every target
    evaluate = target_evaluator(actuate, node_indices(model, NODES), False)
    args = (jnp.asarray(targets), jnp.broadcast_to(jnp.eye(3), (6, 2, 3, 3)),
            jnp.ones(2), jnp.asarray(1.0))
    at = lambda U: [np.asarray(x) for x in  # noqa: E731
                    evaluate(model, as_traced(TIGHT), jnp.asarray(U), *args)[:2]]
    U0 = np.tile([0.5, 0.5], (6, 1))
    J = at(U0)[1]
    h = 1e-6
    for k in range(2):
        step = h * np.eye(2)[k]
        fd = (at(U0 + step)[0] - at(U0 - step)[0]) / (2 * h)
        assert np.linalg.norm(J[:, :, k] - fd) <= 1e-6 * np.linalg.norm(fd)

    # optax L-BFGS on the same batch (same compiled solves) reaches the reachable ones
    lb = sj.solve_inverse(model, actuate, NODES, targets, [0.5, 0.5], lower=lower,
                          upper=upper, tolerance=1e-7, settings=TIGHT, method="lbfgs",
                          max_steps=100)
    assert np.all(lb.reached[:4]) and np.all(lb.relative_error[:4] <= REACH), lb.messages
    assert np.all(lb.unreachable[4:]) and np.all(lb.u[:, 0] >= 0.0)

    # a static solve that cannot converge (no tolerance can be met, few load halvings):
    # reported with its cause, nothing tried, no error value
    never = sj.StaticSettings(tolerance=0.0, step_tolerance=0.0, stagnation_level=0.0,
                              min_step_fraction=0.25)
    bad = sj.solve_inverse(model, actuate, NODES, targets, [0.5, 0.5], settings=never)
    assert np.all(bad.solve_failed) and not np.any(bad.reached | bad.unreachable)
    assert np.all(np.isnan(bad.error)) and np.all(bad.iterations == 0)
    assert np.all(np.isnan(bad.positions))
    assert "static solve failed at the start point" in bad.messages[0]
    assert "Newton reached its iteration limit" in bad.messages[0]


def test_spatial_four_actuators(spatial):
    """3-D robot, 4 moments: random reachable targets for the middle and tip nodes."""
    model, actuate = spatial
    rng = np.random.default_rng(2)
    U = rng.uniform(-1.0, 1.0, (3, 4))
    targets = forward(model, actuate, U, [4, 8])
    res = sj.solve_inverse(model, actuate, [("arm", 4), ("arm", -1)], targets, np.zeros(4),
                           tolerance=TOL, settings=TIGHT)
    check_reached(res, U, targets, slice(None))


@pytest.mark.slow
def test_frame_target_closed_form(planar):
    """A target frame: the tip of the arc turned by M about z. Position and orientation
    together fix the tip moment (the mid one is 0)."""
    model, actuate = planar
    M = 0.9
    p = np.array([np.sin(M) / M, (1 - np.cos(M)) / M, 0.0])
    c, s = np.cos(M), np.sin(M)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    res = sj.solve_inverse(model, actuate, [8], p[None], [0.3, 0.3], rotations=R[None],
                           tolerance=TOL, settings=TIGHT)
    assert res.reached[0] and res.relative_error[0] <= REACH, res.messages
    np.testing.assert_allclose(res.u[0], [0.0, M], atol=1e-6)


@pytest.mark.slow
def test_twenty_random_targets_each_robot(planar, spatial):
    """The issue's count: 20 reachable random targets for each robot, in chunks of the
    batch sizes of the tests above (their compiled programs, when run in one session)."""
    rng = np.random.default_rng(3)
    for (model, actuate), P, chunk in ((planar, 2, 6), (spatial, 4, 3)):
        U = rng.uniform(-1.0, 1.0, (20, P))
        targets = forward(model, actuate, U, NODES)
        res = sj.solve_inverse(model, actuate, NODES, targets, np.zeros(P), tolerance=TOL,
                               settings=TIGHT, chunk=chunk)
        assert res.u.shape == (20, P)
        check_reached(res, U, targets, slice(None))


@pytest.mark.slow
def test_base_pose_actuation_closed_form():
    """A pose actuator: the clamp's position (the held node follows ``p0``, whose
    derivative the implicit gradient carries) moved along y by D, with the tip moment M:
    the arc of curvature M/EI shifted by D. The targets on it give back (D, M)."""
    model = robot()
    actuate = sj.leaf_actuation(model, [("p0", (0, 1)), ("nodal_follower", (-1, 5))])
    M, D = 0.9, 0.05
    arc = np.array([[np.sin(M * s) / M, D + (1 - np.cos(M * s)) / M, 0.0] for s in (0.5, 1)])
    res = sj.solve_inverse(model, actuate, NODES, arc, [0.0, 0.3], tolerance=TOL,
                           settings=TIGHT)
    assert res.reached[0] and res.relative_error[0] <= REACH, res.messages
    np.testing.assert_allclose(res.u[0], [D, M], atol=1e-8)


def test_bad_input_names_the_argument(planar):
    model, actuate = planar
    tip = np.array([[0.9, 0.1, 0.0]])
    cases = [
        (dict(nodes=[("arm", 9)]), "nodes[0]: unknown node 9"),
        (dict(nodes=[("hand", 0)]), "nodes[0]: unknown rod 'hand'"),
        (dict(nodes=[12]), "nodes[0]: unknown node 12"),
        (dict(positions=np.zeros((1, 2, 3))), "positions: expected shape (1, 3)"),
        (dict(lower=[1.0, 0.0], upper=[0.0, 1.0]), "lower: lower[0] = 1.0 exceeds upper[0]"),
        (dict(lower=[0.0]), "lower: expected shape (2,)"),
        (dict(u0=[0.0, 0.0, 0.0]), "u0: expected shape (2,)"),
        (dict(rotations=np.eye(3)), "rotations: expected shape (1, 3, 3)"),
        (dict(weights=[-1.0]), "weights: expected 1 positive weights"),
        (dict(method="newton"), "method: unknown method 'newton'"),
        (dict(chunk=0), "chunk: expected a positive int"),
    ]
    for change, message in cases:
        args = dict(nodes=[8], positions=tip, u0=[0.0, 0.0])
        args.update(change)
        with pytest.raises(ValueError) as info:
            sj.solve_inverse(model, actuate, **args)
        assert message in str(info.value), (change, str(info.value))
    for actuators, message in (
            ([("stiffnes", 0)], "actuators: the model has no array 'stiffnes'"),
            ([("nodal_follower", (9, 5))], "actuators[0]: index (9, 5) is outside"),
            ([("nodal_dead", (8, 0))], "actuators[0]: this model was built without "
                                       "world-frame nodal loads ('nodal_dead' is None)"),
            ([("nodal_follower", (8, 5)), ("nodal_follower", (-1, 5))],
             "actuators[1]: writes entries of 'nodal_follower' another actuator")):
        with pytest.raises(ValueError) as info:
            sj.leaf_actuation(model, actuators)
        assert message in str(info.value), str(info.value)


def test_least_squares_on_rosenbrock_with_a_bound():
    """The batched bounded least squares alone, on Rosenbrock's residuals
    r = (10 (u2 - u1^2), 1 - u1): minimum 0 at (1, 1); with u1 <= 0.5 the minimum is at
    the bound, (0.5, 0.25), cost 0.5 * 0.5^2, a stationary point of the box."""
    from simsoft_jax.studies.least_squares import Outcome, least_squares

    def evaluate(U):
        u1, u2 = U[:, 0], U[:, 1]
        r = np.stack([10 * (u2 - u1 ** 2), 1 - u1], axis=1)
        J = np.zeros((len(U), 2, 2))
        J[:, 0, 0], J[:, 0, 1], J[:, 1, 0] = -20 * u1, 10.0, -1.0
        return r, J, np.ones(len(U), bool)

    error = lambda r: np.max(np.abs(r), axis=1)  # noqa: E731
    U0 = np.array([[-1.2, 1.0], [-1.2, 1.0]])
    lower = np.array([-np.inf, -np.inf])
    for method in ("levenberg_marquardt", "lbfgs"):
        sol = least_squares(evaluate, U0, lower, np.array([np.inf, np.inf]), error, 1e-10,
                            method=method, max_steps=200)
        assert np.all(sol.outcome == Outcome.REACHED), (method, sol.outcome)
        np.testing.assert_allclose(sol.u, 1.0, atol=1e-9)
        sol = least_squares(evaluate, U0, lower, np.array([0.5, np.inf]), error, 1e-10,
                            method=method, max_steps=200)
        assert np.all(sol.outcome == Outcome.STATIONARY), (method, sol.outcome)
        np.testing.assert_allclose(sol.u, [[0.5, 0.25]] * 2, atol=1e-7)
        assert np.all(sol.active == [True, False])
