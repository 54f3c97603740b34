"""The swept check of an update (:mod:`simsoft_jax.solvers.swept_check`): a Newton update or
a load-continuation prediction that would carry a rod through another rod or through an
obstacle is cut back. References are the geometry itself: two straight rods crossing at
right angles (top along x at height z, bottom along y at 0, contact radius r each) pass
through each other exactly when the top one goes from z > r to z < r (its centreline
closer than one radius to the other's, or beyond it), wherever the crossing lies on the
chords (at a node or inside an element); a node crosses a plane's surface when its
signed height goes from > 0 to < 0.
"""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from simsoft_jax.model.model import build_model
from simsoft_jax.scene.scene import Scene
from simsoft_jax.solvers import swept_check

N, L, R_C = 4, 0.2, 0.005


def _rod(name, along_y, z, shift=0.0):
    return {"name": name, "elements": N, "geometry": {"kind": "straight", "length": L},
            "base": {"position": [shift, -L / 2, z] if along_y else [-L / 2, shift, z],
                     "rotation": [0.0, 0.0, np.pi / 2 if along_y else 0.0]},
            "stiffness": {"EA": 1e7, "GAy": 1e7, "GAz": 1e7, "GJ": 1.0, "EIy": 1.0,
                          "EIz": 1.0},
            "inertia": {"rhoA": 1.0, "rhoJ": 1e-6, "rhoIy": 1e-6, "rhoIz": 1e-6}}


def _model(shift=0.0, obstacle=False):
    scene = {"solver": {"kind": "dynamic", "t_end": 0.1, "dt": 0.01},
             "rods": [_rod("top", False, 0.0, shift), _rod("bottom", True, 0.0, shift)],
             "contact": {"radius": R_C, "self": not obstacle}}
    if obstacle:
        scene["rods"] = scene["rods"][:1]
        scene["obstacles"] = [{"name": "floor", "kind": "plane", "point": [0, 0, -0.01],
                               "normal": [0, 0, 1]}]
    return build_model(Scene.from_dict(scene))


def _lifted(model, z):
    """Node positions with the top rod (the first N + 1 nodes) at height z (m)."""
    return jnp.asarray(model.p0).at[:N + 1, 2].add(z)


@pytest.mark.parametrize("shift", [0.0, 0.3 * L / N], ids=["at-a-node", "inside-an-element"])
def test_rod_passing_through_another_is_detected_and_cut_back(shift):
    model = _model(shift)
    above = _lifted(model, 3 * R_C)
    for z, passing in ((-3 * R_C, True), (0.5 * R_C, True), (1.5 * R_C, False),
                       (10 * R_C, False)):
        assert bool(swept_check.passes(model, above, _lifted(model, z))) is passing, z
    # moving up is never a pass; nor is a move that starts already closer than r
    assert not bool(swept_check.passes(model, _lifted(model, 0.5 * R_C),
                                       _lifted(model, -3 * R_C)))
    # from z = 3r towards z = -4r: the largest fraction 2^-k that keeps z > r is 1/4
    move = lambda t: _lifted(model, 3 * R_C - t * 7 * R_C)   # noqa: E731
    assert float(swept_check.cut_back(model, above, move, 1.0)) == 0.25


def test_rods_sliding_past_each_other_are_not_a_pass():
    """The top rod moved sideways along the bottom one (and along itself), keeping its
    height above r: no pass, though the crossing moves from one chord pair to another."""
    model = _model()
    above = _lifted(model, 2 * R_C)
    moved = above.at[:N + 1, 1].add(0.7 * L / N).at[:N + 1, 0].add(0.4 * L / N)
    assert not bool(swept_check.passes(model, above, moved))


def test_node_sinking_through_an_obstacle_surface_is_detected():
    model = _model(obstacle=True)
    p = jnp.asarray(model.p0)      # the rod 0.01 m above the floor
    assert bool(swept_check.passes(model, p, p.at[2, 2].add(-0.011)))
    assert not bool(swept_check.passes(model, p, p.at[:, 2].add(-0.009)))
    assert float(swept_check.cut_back(model, p, lambda t: p.at[:, 2].add(-0.05 * t),
                                      1.0)) == 0.125


def test_models_without_contact_are_not_checked():
    scene = {"solver": {"kind": "dynamic", "t_end": 0.1, "dt": 0.01},
             "rods": [_rod("top", False, 0.0), _rod("bottom", True, 0.0)]}
    model = build_model(Scene.from_dict(scene))
    assert not swept_check.checked(model)
    assert swept_check.cut_back(model, model.p0, None, 1.0) == 1.0


@pytest.mark.slow     # compiling the rod-contact dynamics: ~30 s on a loaded 2-core machine
def test_heavy_rope_dropped_dynamically_with_a_large_step_rests_on_top():
    """Two ropes pinned at both ends, crossing at right angles, the upper one (8 times
    denser, so it sags twice as far) starting 4 r above the lower one, under gravity with
    mass damping, stepped at dt = 0.1 s (ten steps per second, against a sag period of
    ~0.4 s): the upper one lands on the lower and stays on top, the centrelines one
    diameter apart at the crossing (less the penetration of the penalty), from the first
    step after the landing on."""
    import simsoft_jax as sj
    r, length, n = 0.005, 0.4, 20

    def rope(name, along_y, z, density):
        return {"name": name, "elements": n,
                "material": {"E": 1e6, "G": 1e6 / 3, "density": density,
                             "mass_damping": 10.0},
                "section": {"shape": "circle", "diameter": 2 * r},
                "geometry": {"kind": "straight", "length": length},
                "base": {"position": [0.0, -length / 2, z] if along_y else
                         [-length / 2, 0.0, z],
                         "rotation": [0.0, 0.0, np.pi / 2 if along_y else 0.0]}}

    scene = {"solver": {"kind": "dynamic", "t_end": 1.0, "dt": 0.1, "rho_inf": 0.0},
             "gravity": {"vector": [0, 0, -9.81]},
             "rods": [rope("lower", False, 0.0, 1000.0), rope("upper", True, 4 * r, 8000.0)],
             "constraints": [{"kind": "pin", "rod": k, "node": i}
                             for k in ("lower", "upper") for i in (0, -1)],
             "contact": {"self": True}}
    result = sj.run(scene)
    assert result.converged, result.message
    apart = (result.positions("upper")[:, n // 2, 2]
             - result.positions("lower")[:, n // 2, 2]) / (2 * r)
    assert np.all(apart > 0.98)                 # never closer, never through
    np.testing.assert_allclose(apart[2:], 1.0, atol=0.01)   # resting on top


# --- the broad phase of the rods' check against every pair of chords ---------------------

RODS, PER_ROD = 4, 8


def _rods_model():
    """Four free straight rods of 8 elements each, rod-rod contact of radius R_C (their
    positions are replaced by the sweeps below)."""
    rods = [dict(_rod(f"rod{k}", False, 0.01 * k), elements=PER_ROD) for k in range(RODS)]
    scene = {"solver": {"kind": "dynamic", "t_end": 0.1, "dt": 0.01}, "rods": rods,
             "contact": {"radius": R_C, "self": True}}
    return build_model(Scene.from_dict(scene))


def _brute_force(x, radius):
    """Every pair of chords not sharing a node, in every part i -> i+1 of the sweep x
    (S+1, N, 3), by the rule of the module docstring written out here: the closest points
    of the two lines (from the 2x2 normal equations) within both chords extended by half
    a chord (not past a rod's free end) in both states, the chords at an angle above
    PARALLEL_SINE, and the gap along the common normal (turned to state i's side) going
    from above r to below r."""
    ends = [k * (PER_ROD + 1) for k in range(RODS)]
    a = np.array([n for k in ends for n in range(k, k + PER_ROD)])        # element nodes
    first = np.isin(a, ends)
    last = np.isin(a + 1, [k + PER_ROD for k in ends])
    lo, hi = np.where(first, 0.0, -0.5), np.where(last, 1.0, 1.5)
    e, f = np.triu_indices(len(a), 1)
    keep = (a[f] != a[e] + 1) & (a[e] != a[f] + 1)
    e, f = e[keep], f[keep]

    def state(y):
        A0, B0 = y[a[e]], y[a[f]]
        u, v, w = y[a[e] + 1] - A0, y[a[f] + 1] - B0, B0 - A0
        c = np.cross(u, v)
        sine = np.linalg.norm(c, axis=1) / (np.linalg.norm(u, axis=1)
                                            * np.linalg.norm(v, axis=1))
        angled = sine > swept_check.PARALLEL_SINE      # (parallel lines: any normal, s, t)
        n = np.where(angled[:, None], c, [0.0, 0.0, 1.0])
        n = n / np.linalg.norm(n, axis=1)[:, None]
        # A0 + s u - (B0 + t v) is normal to u and v
        M = np.stack([np.stack([np.sum(u * u, 1), -np.sum(u * v, 1)], -1),
                      np.stack([np.sum(u * v, 1), -np.sum(v * v, 1)], -1)], 1)
        M = np.where(angled[:, None, None], M, np.eye(2))
        rhs = np.stack([np.sum(w * u, 1), np.sum(w * v, 1)], -1)[..., None]
        s, t = np.linalg.solve(M, rhs)[..., 0].T
        inside = (s >= lo[e]) & (s <= hi[e]) & (t >= lo[f]) & (t <= hi[f])
        return n, np.sum(w * n, 1), inside & angled

    r = 0.5 * (radius[e] + radius[f])
    for y0, y1 in zip(x[:-1], x[1:]):
        (n0, g0, ok0), (n1, g1, ok1) = state(y0), state(y1)
        g1 = g1 * np.sign(np.sum(n0 * n1, 1)) * np.sign(g0)
        if np.any(ok0 & ok1 & (np.abs(g0) > r) & (g1 < r)):
            return True
    return False


def _polyline(rng, start, direction, bend=0.3):
    """PER_ROD + 1 nodes (m) from ``start`` one chord L/N apart, turning a little."""
    d, out = np.asarray(direction, float), [np.asarray(start, float)]
    for _ in range(PER_ROD):
        d = d / np.linalg.norm(d) + bend * rng.normal(size=3) / 3
        out.append(out[-1] + L / N * d / np.linalg.norm(d))
    return np.array(out)


def _sweeps(rng):
    """Sweeps (p0, p1, kind) (N,3) of the four rods: a rod moved across another one
    (through it, or stopping within or just outside one radius), near misses passing
    just beyond a rod's free end, parallel and nearly parallel chords moved through each
    other, and all rods heaped in a small box with moves of a few radii."""
    h = L / N
    for _ in range(12):     # rods 0 and 1 crossing; rods 2, 3 far away
        z0 = R_C * rng.uniform(1.2, 4.0)
        z1 = R_C * rng.choice([rng.uniform(-4, -1), rng.uniform(-0.9, 0.9),
                               rng.uniform(1.001, 1.5), rng.uniform(1.5, 3)])
        c = rng.uniform(-1.5 * h, 1.5 * h, 3) * [1, 1, 0]
        lower = _polyline(rng, [-L / 2, 0, 0], [1, 0, 0], 0.1)
        upper = _polyline(rng, [c[0], c[1] - L / 2, z0], [rng.normal(0, 0.3), 1, 0], 0.1)
        tilt = rng.normal(0, 0.05, 3)
        far = [_polyline(rng, [1.0, k, 1.0], [1, 0, 0]) for k in (0.0, 0.1)]
        p0 = np.concatenate([lower, upper] + far)
        moved = upper + [0, 0, z1 - z0] + tilt * (upper - upper[0])[:, [1]]
        yield p0, np.concatenate([lower, moved] + far), "crossing"
    for _ in range(8):      # (near) misses: the upper rod swept down just beyond, or just
        # within, the lower one's free end (its chords are not extended past it)
        lower = _polyline(rng, [-L / 2, 0, 0], [1, 0, 0], 0.0)
        gap = R_C * rng.choice([-1, 1]) * rng.uniform(0.05, 1.0)
        upper = _polyline(rng, [lower[-1, 0] + gap, -L / 2, 3 * R_C], [0, 1, 0], 0.0)
        far = [_polyline(rng, [1.0, k, 1.0], [1, 0, 0]) for k in (0.0, 0.1)]
        p0 = np.concatenate([lower, upper] + far)
        yield p0, np.concatenate([lower, upper - [0, 0, 6 * R_C]] + far), "near miss"
    for angle in (0.0, 0.02, 0.2):   # (nearly) parallel chords moved through each other
        lower = _polyline(rng, [-L / 2, 0, 0], [1, 0, 0], 0.0)
        upper = _polyline(rng, [-L / 2, 0, 3 * R_C], [1, np.sin(angle), 0], 0.0)
        far = [_polyline(rng, [1.0, k, 1.0], [1, 0, 0]) for k in (0.0, 0.1)]
        p0 = np.concatenate([lower, upper] + far)
        yield p0, np.concatenate([lower, upper - [0, 0, 6 * R_C]] + far), "parallel"
    for _ in range(30):     # many rods heaped in a box of a few chords, moved a few radii
        p0 = np.concatenate([_polyline(rng, rng.uniform(0, 2 * h, 3), rng.normal(size=3), 1.0)
                             for _ in range(RODS)])
        moves = rng.normal(size=(4, 3)) * R_C * rng.uniform(0.5, 4)
        s = np.linspace(0, 1, len(p0))[:, None]
        yield p0, p0 + moves[0] + moves[1] * np.sin(7 * s) + moves[2] * np.cos(13 * s) \
            + moves[3] * s, "heap"


@pytest.mark.parametrize("few", [None, 1], ids=["broad-phase", "overflow-to-every-pair"])
def test_rods_pass_equals_every_pair_tested(monkeypatch, few):
    """The rods' check (pairs of overlapping swept boxes, or every pair when more overlap
    than ``SWEPT_PAIRS`` per element) answers as the brute-force test of every pair of
    chords, on sweeps that pass and that do not of each kind."""
    if few is not None:
        monkeypatch.setattr(swept_check, "SWEPT_PAIRS", few)
    model = _rods_model()
    radius = np.asarray(model.contact_radius)
    check = jax.jit(lambda x: swept_check.rods_pass(model, x))
    t = np.linspace(0.0, 1.0, swept_check.SAMPLES + 1)[:, None, None]
    e, f = swept_check.chord_pairs(model.structure)
    seen = set()
    for p0, p1, kind in _sweeps(np.random.default_rng(7)):
        x = (1.0 - t) * p0 + t * p1
        expected = _brute_force(x, radius)
        assert bool(check(jnp.asarray(x))) is expected, kind
        low, high = (np.asarray(v) for v in swept_check.swept_boxes(model, jnp.asarray(x)))
        overlapping = np.sum(np.all((low[e] <= high[f]) & (low[f] <= high[e]), -1))
        seen.add((kind, expected, bool(overlapping > (few or swept_check.SWEPT_PAIRS)
                                       * model.structure.n_elements)))
    # both answers for each kind of sweep; the pairs compacted, and (tiny room) not
    for kind in ("crossing", "near miss", "heap"):
        assert {s[1] for s in seen if s[0] == kind} == {True, False}, kind
    assert False in {s[2] for s in seen}
    if few is not None:
        assert {s[1] for s in seen if s[2]} == {True, False}
