"""Rod-rod contact in statics (issue 14, ``[contact] self = true``): two crossing rods
pressed together against equilibrium and the penalty law, Newton's third law, the
symmetric contact point, gradients against central finite differences, the result's
``contacts.rods`` entry, and the broad phase's neighbour exclusion against a brute-force
search over all element pairs written here.

One structure serves the solves: rod "top" along x, its two end nodes held in x, y and
the rotations but free to slide in z (set on the model: the scene validator rightly
refuses a rod whose supports leave a rigid motion, and here the contact holds it), is
pushed by a force F at its middle onto rod "bottom" along y, clamped at both ends; they
cross at both middle nodes. The top rod is held in z by the contact alone, so the
contact force on it equals F by equilibrium.
"""
import dataclasses
import json
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.couplings import broad_phase, rod_pairs
from simsoft_jax.solvers import statics
from simsoft_jax.model.model import build_model
from simsoft_jax.pipeline.results import Result
from simsoft_jax.scene.scene import Scene
from simsoft_jax.physics.terms import rod_contact
from simsoft_jax.physics.terms.contact import SMOOTHING

N, L, R_C, EI, F = 4, 0.2, 0.005, 1.0, 10.0       # elements, m, m, N m^2, N
POINTS = 4                                          # stations: sub-chords per element
EPS = SMOOTHING * 2 * R_C                           # smoothing width of the pair penalty


def _rod(name, along_y, z):
    return {"name": name, "elements": N, "geometry": {"kind": "straight", "length": L},
            "base": {"position": [0.0, -L / 2, z] if along_y else [-L / 2, 0.0, z],
                     "rotation": [0.0, 0.0, np.pi / 2 if along_y else 0.0]},
            "stiffness": {"EA": 1e7, "GAy": 1e7, "GAz": 1e7, "GJ": 1.0, "EIy": EI,
                          "EIz": EI},
            "inertia": {"rhoA": 1.0, "rhoJ": 1e-6, "rhoIy": 1e-6, "rhoIz": 1e-6}}


SCENE = {"solver": {"kind": "static", "load_steps": 5},
         # the top rod starts a smoothing width into the bottom one (not at zero force,
         # where the penalty's cubic start has no stiffness)
         "rods": [_rod("top", False, 2 * R_C - EPS), _rod("bottom", True, 0.0)],
         "constraints": [{"kind": "clamp", "rod": r, "node": n}
                         for r in ("top", "bottom") for n in (0, -1)],
         "loads": [{"kind": "force", "rod": "top", "node": N // 2,
                    "vector": [0.0, 0.0, -F]}],
         "contact": {"radius": R_C, "self": True, "max_pairs": 4,
                     "quadrature_points": POINTS}}
TOP_MID, BOTTOM_MID = N // 2, (N + 1) + N // 2       # global node indices


def penetration(force, point_stiffness):
    """The penetration (m) at which the C2 penalty of a point contact of stiffness
    ``l k`` (N/m) pushes with ``force`` (N): ``F = l k delta^2 / (2 eps)`` below the
    smoothing width eps, ``F = l k (delta - eps/2)`` beyond it."""
    cubic = np.sqrt(2.0 * EPS * force / point_stiffness)
    return cubic if cubic < EPS else force / point_stiffness + EPS / 2


def point_stiffness(model):
    """``l k``: the mean sub-chord length times the penalty stiffness (N/m)."""
    return float(model.contact_stiffness[0]) * (L / N) / POINTS


@pytest.fixture(scope="module")
def model():
    m = build_model(Scene.from_dict(SCENE))
    free = np.array(m.structure.free).reshape(-1, 6)
    free[[0, N], 2] = True            # the top rod's ends slide in z (local z = world z)
    return m.replace(structure=dataclasses.replace(m.structure,
                                                   free=tuple(free.ravel().tolist())))


@pytest.fixture(scope="module")
def solved(model):
    eq = statics.solve_static(model)
    assert bool(eq.converged), eq.message()
    return eq


def test_crossing_rods_newtons_third_law_and_force_equals_the_load(model, solved):
    report = rod_pairs.report(model, solved.R, solved.p)
    top, bottom = report["rod_force"]["top"], report["rod_force"]["bottom"]
    # the top rod is held in z by the contact only: its contact force is F, upward
    np.testing.assert_allclose(top, [0.0, 0.0, F], atol=1e-7 * F)
    np.testing.assert_allclose(bottom, -top, atol=1e-9 * F)          # third law
    np.testing.assert_allclose(report["force"], 0.0, atol=1e-9 * F)
    # the sum of the pair magnitudes: the normals tilt a little with the sag
    np.testing.assert_allclose(report["normal_force"], F, rtol=1e-4)


def test_symmetric_crossing_contact_point_and_penetration(model, solved):
    """By symmetry the rods touch at their middles, which stay on the z axis; the
    penetration at that point follows the penalty law (:func:`penetration`) with the
    point stiffness ``l k`` of one sub-chord length (a crossing counted once: the
    partition of unity over the four sub-chord pairs at the two middle nodes; exact for
    collinear sub-chords, here the sag's kink of the chords at the nodes leaves 0.4 %
    in the weights, 0.2 % in the penetration)."""
    p = np.asarray(solved.p)
    np.testing.assert_allclose(p[[TOP_MID, BOTTOM_MID], :2], 0.0, atol=1e-12)
    # the deflected rods are mirror-symmetric about the crossing
    top, bottom = p[:N + 1], p[N + 1:]
    np.testing.assert_allclose(top[:, 2], top[::-1, 2], atol=1e-12)
    np.testing.assert_allclose(bottom[:, 2], bottom[::-1, 2], atol=1e-12)
    delta = penetration(F, point_stiffness(model))
    gap = p[TOP_MID, 2] - p[BOTTOM_MID, 2]
    np.testing.assert_allclose(2 * R_C - gap, delta, rtol=5e-3)
    report = rod_pairs.report(model, solved.R, solved.p)
    # the sub-chords at the kinked nodes reach a little deeper than the nodes
    np.testing.assert_allclose(report["max_penetration"], 2 * R_C - gap, rtol=1e-3)


@pytest.mark.slow
def test_gradients_through_rod_contact_match_finite_differences(model):
    """d(middle heights)/d(penalty stiffness scale, bottom rod's bending stiffness
    scale) by the implicit derivative against central differences."""
    bending = np.zeros(model.stiffness.shape)
    bending[N:, 4:] = 1.0                         # EIy, EIz of the bottom rod's elements

    def heights(a):
        m = model.replace(contact_stiffness=model.contact_stiffness * (1.0 + a[0]),
                          stiffness=model.stiffness * (1.0 + a[1] * bending))
        eq = statics.solve_static(m)
        return eq.p[jnp.array([TOP_MID, BOTTOM_MID]), 2]

    jac = jax.jacfwd(heights)(jnp.zeros(2))
    step = 1e-3
    for k in range(2):
        e = np.eye(2)[k] * step
        fd = (np.asarray(heights(jnp.asarray(e))) - np.asarray(heights(jnp.asarray(-e)))) / (
            2 * step)
        np.testing.assert_allclose(jac[:, k], fd, rtol=1e-4, atol=1e-4 * np.abs(fd).max())
    # and against the penalty law: the penetration (cubic branch here) falls with k as
    # delta ~ k^(-1/2), so d(gap)/d(scale) = delta / 2
    delta = penetration(F, point_stiffness(model))
    assert delta < EPS
    np.testing.assert_allclose(jac[0, 0] - jac[1, 0], delta / 2, rtol=5e-3)


def test_more_pairs_than_max_pairs_stop_the_static_solve_with_a_status_naming_it(model,
                                                                                  solved):
    """The crossing rods meet at their middle nodes, where the two elements of one rod
    meeting there face the two of the other: 4 element pairs, ``max_pairs``. With the
    bottom rod turned under the top one, parallel to it (same depth), each top element
    faces two or three bottom ones, more pairs than 4: every load level fails on the
    overflow, so the continuation stops at load level 0 with the cause ``contact_pairs``
    (not ``nonfinite``) and a message naming ``[contact] max_pairs``, keeping the last
    converged state (the start). The structure is the crossing's (``max_pairs`` is part
    of a structure), so the solve is the program compiled for it. With the 4 pairs of
    the crossing the same solve converges with the top rod resting on the bottom one:
    their middles a sum of radii apart, less a penetration within the penalty's
    smoothing width."""
    rods = {rod.name: rod for rod in model.structure.rods}
    top, bottom = (slice(rods[n].first_node, rods[n].first_node + rods[n].nodes)
                   for n in ("top", "bottom"))
    p0, R0 = np.array(model.p0), np.array(model.R0)
    p0[bottom], R0[bottom] = p0[top] - [0.0, 0.0, 2 * R_C - EPS], R0[top]
    parallel = model.replace(p0=p0, R0=R0)
    eq = statics.solve_static(parallel)
    assert not bool(eq.converged)
    assert sj.Status(int(eq.status)) == sj.Status.STEP_TOO_SMALL
    assert sj.Status(int(eq.cause)) == sj.Status.CONTACT_PAIRS
    assert "[contact] max_pairs" in eq.message()
    assert float(eq.load_level) == 0.0
    np.testing.assert_array_equal(eq.p, p0)
    gap = float(solved.p[TOP_MID, 2] - solved.p[BOTTOM_MID, 2])
    assert 2 * R_C - EPS < gap < 2 * R_C


def test_result_contacts_entry_for_rod_pairs(model, solved, tmp_path):
    result = Result(Scene.from_dict(SCENE), model, jax.device_get(solved), 0.0, 0.0)
    path = result.save(tmp_path / "crossing.json")
    rods = json.loads(path.read_text())["contacts"]["rods"]
    assert set(rods) == {"normal_force", "force", "rod_force", "max_penetration", "nodes"}
    np.testing.assert_allclose(rods["normal_force"], F, rtol=1e-4)
    np.testing.assert_allclose(rods["rod_force"]["top"], [0.0, 0.0, F], atol=1e-6)
    # the elements touching at the crossing: the two around each middle node
    assert rods["nodes"] == {"top": [1, 2, 3], "bottom": [1, 2, 3]}


def _hairpin(n_leg, h):
    """Node positions and frames of a rod folded into a hairpin: a leg of n_leg elements
    of length h along +x, a bend of 2 elements on a semicircle of radius ``h/sqrt(2)``
    (chords of length h), and a leg back along -x, ``sqrt(2) h`` above the first."""
    rho = h / np.sqrt(2.0)
    pts = [[i * h, 0.0, 0.0] for i in range(n_leg + 1)]
    pts += [[n_leg * h + rho, 0.0, rho], [n_leg * h, 0.0, 2 * rho]]
    pts += [[(n_leg - i) * h, 0.0, 2 * rho] for i in range(1, n_leg + 1)]
    pts = np.array(pts)
    R = []
    for i in range(len(pts)):
        t = pts[min(i + 1, len(pts) - 1)] - pts[max(i - 1, 0)]
        t = t / np.linalg.norm(t)
        R.append(np.stack([t, [0.0, 1.0, 0.0], np.cross(t, [0.0, 1.0, 0.0])], 1))
    return np.array(R), pts


def test_broad_phase_finds_the_folded_contacts_and_excludes_neighbours():
    """A hairpin whose legs lie 1.41 h apart, in contact with a contact radius r of 0.75
    element lengths h, so that a rod's own neighbours (sharing a node, or one element
    apart) are within reach. Brute force over all element pairs: every pair whose
    sub-chords come within 2 r and whose arclength gap is beyond the exclusion must be a
    candidate, and no candidate may be a neighbour."""
    n_leg, h = 6, 0.01
    r = 0.75 * h
    R, p = _hairpin(n_leg, h)
    E = len(p) - 1
    scene = {"solver": {"kind": "static"},
             "rods": [{"name": "hairpin", "elements": E,
                       "geometry": {"kind": "straight", "length": E * h},
                       "stiffness": {"EA": 1.0, "GAy": 1.0, "GAz": 1.0, "GJ": 1.0,
                                     "EIy": 1.0, "EIz": 1.0},
                       "inertia": {"rhoA": 1.0, "rhoJ": 1.0, "rhoIy": 1.0, "rhoIz": 1.0}}],
             "constraints": [{"kind": "clamp", "rod": "hairpin", "node": 0}],
             "contact": {"radius": r, "self": True, "max_pairs": 32,
                         "quadrature_points": 2}}
    model = build_model(Scene.from_dict(scene))
    pairs = jax.device_get(jax.jit(rod_pairs.find_pairs)(model, jnp.asarray(R),
                                                          jnp.asarray(p)))
    assert not pairs.overflow
    found = {(int(e), int(f)) for e, f, on in zip(pairs.e, pairs.f, pairs.active) if on}
    exclusion = float(model.self_exclusion)
    length = np.asarray(model.length)
    s0 = np.concatenate([[0.0], np.cumsum(length)])
    X = [np.asarray(rod_contact.stations(R[e], p[e], R[e + 1], p[e + 1], length[e], 2))
         for e in range(E)]

    def touching(e, f):         # sub-chords within 2 r (sampled densely)
        u = np.linspace(0.0, 1.0, 21)[:, None]
        for a in range(2):
            A = X[e][a] + u * (X[e][a + 1] - X[e][a])
            for b in range(2):
                B = X[f][b] + u * (X[f][b + 1] - X[f][b])
                if np.min(np.linalg.norm(A[:, None] - B[None], axis=-1)) < 2 * r:
                    return True
        return False

    expected = {(e, f) for e in range(E) for f in range(e + 1, E)
                if s0[f] - s0[e + 1] >= exclusion and touching(e, f)}
    assert len(expected) >= n_leg - 2                  # the legs do touch
    assert expected <= found
    assert all(s0[f] - s0[e + 1] >= exclusion for e, f in found)
    # without the exclusion the neighbours would be candidates: they are within reach
    assert touching(0, 1) and touching(0, 2)


def hairpin_model(elements, h, clamped):
    """A unit-stiffness rod of ``elements`` elements of length ``h`` with self-contact
    (radius 0.75 h, 32 pairs, 2 contact points), node 0 clamped or free."""
    return build_model(Scene.from_dict({
        "solver": {"kind": "static"},
        "rods": [{"name": "hairpin", "elements": elements,
                  "geometry": {"kind": "straight", "length": elements * h},
                  "stiffness": {"EA": 1.0, "GAy": 1.0, "GAz": 1.0, "GJ": 1.0, "EIy": 1.0,
                                "EIz": 1.0},
                  "inertia": {"rhoA": 1.0, "rhoJ": 1.0, "rhoIy": 1.0, "rhoIz": 1.0}}],
        "constraints": [{"kind": "clamp", "rod": "hairpin", "node": 0}] if clamped else [],
        "contact": {"radius": 0.75 * h, "self": True, "max_pairs": 32,
                    "quadrature_points": 2}}))


def test_tracked_pairs_hold_every_pair_within_their_motion():
    """Pairs found once with a motion allowance (the dynamics' broad phase, once per
    step) against pairs found afresh: the hairpin's upper leg lifted by one element
    length h (no leg contact there) and tracked with motion 1.01 h; lowered back (every
    station moves by h), the pairs found there are all among the tracked ones, which
    :func:`rod_pairs.refresh` keeps; found without the allowance they miss them; lowered
    by 2 h the pairs are found again there."""
    n_leg, h = 6, 0.01
    R, p = _hairpin(n_leg, h)
    E = len(p) - 1
    model = hairpin_model(E, h, clamped=True)
    upper = p[:, 2] > 0.75 * h                                # the upper leg's nodes
    R, lifted = jnp.asarray(R), jnp.asarray(p + np.outer(upper, [0.0, 0.0, h]))

    def pair_set(pairs):
        pairs = jax.device_get(pairs)
        assert not pairs.overflow
        return {(int(e), int(f)) for e, f, on in zip(pairs.e, pairs.f, pairs.active) if on}

    # each function compiled (eagerly, each of its operations compiles on its own)
    find_pairs, refresh = jax.jit(rod_pairs.find_pairs), jax.jit(rod_pairs.refresh)
    tracked = jax.jit(rod_pairs.track)(model, R, lifted, 1.01 * h)
    back = jnp.asarray(p)
    touching = pair_set(find_pairs(model, R, back, 0.0))
    between_legs = {(e, f) for e, f in touching if e < n_leg <= f - 2}
    assert len(between_legs) >= n_leg - 2                     # the legs touch again
    assert touching <= pair_set(tracked.pairs)
    assert not between_legs & pair_set(find_pairs(model, R, lifted, 0.0))
    np.testing.assert_allclose(jax.jit(rod_pairs.moved)(model, tracked, R, back), h,
                               rtol=1e-12)
    kept = refresh(model, tracked, R, back)
    assert pair_set(kept.pairs) == pair_set(tracked.pairs)
    np.testing.assert_array_equal(kept.stations, tracked.stations)
    lower = jnp.asarray(p - np.outer(upper, [0.0, 0.0, h]))
    again = refresh(model, tracked, R, lower)
    assert pair_set(again.pairs) == pair_set(find_pairs(model, R, lower, 1.01 * h))
    np.testing.assert_allclose(again.stations, jax.jit(rod_pairs.stations)(model, R, lower))


def test_dynamic_rod_contact_with_a_sliding_drive_or_a_displaced_tendon_is_read():
    """Both combine with rod-rod contact in dynamics (tests/test_coupling_tendons.py)."""
    dynamic = {"kind": "dynamic", "dt": 0.01, "t_end": 0.02}
    slid = Scene.from_dict({**SCENE, "solver": dynamic, "constraints": [
        {"kind": "drive", "rod": "top", "node": 0, "times": [0.0, 1.0],
         "rotation": [[0, 0, 0], [0, 0, 0]], "slides_along": [1, 0, 0]}]})
    np.testing.assert_array_equal(slid.constraints[0].slides_along, [1.0, 0.0, 0.0])
    pulled = Scene.from_dict({**SCENE, "solver": dynamic, "tendons": [
        {"name": "t", "rod": "top", "offset": [0.0, 0.001], "displacement": 1e-3}]})
    assert pulled.tendons[0].displacement == 1e-3 and pulled.contact.self_contact


@pytest.mark.parametrize("change, key", [
    ({"contact": {"radius": R_C, "self": False, "max_pairs": 4}}, "contact.max_pairs"),
    ({"contact": {"radius": R_C, "self": 1}}, "contact.self"),
    ({"obstacles": [{"name": "rods", "kind": "sphere", "center": [0.0, 0.0, 1.0],
                     "radius": 0.1}]}, "contact.self"),
])
def test_rod_contact_input_errors_name_the_key(change, key):
    with pytest.raises(ValueError, match=re.escape(key)):
        Scene.from_dict({**SCENE, **change})


@pytest.mark.slow
def test_coil_with_overlapping_turns_opens_until_its_turns_just_touch():
    """Self contact in a solve: a two-turn helix (coil radius 0.02 m, 8 elements a turn)
    whose stress-free pitch, 0.9 (2 r), makes its turns overlap. Contact pushes the
    turns apart; they cannot separate beyond touching (without contact they would spring
    back towards the overlap), so at equilibrium every point of the second turn sits at
    about 2 r from the first: between ``2 r`` minus the largest penetration and ``2 r``.
    The contact forces are internal: their total on the rod vanishes."""
    r = 0.005
    scene = {"solver": {"kind": "static", "load_steps": 5},
             "rods": [{"name": "coil", "elements": 16,
                       "geometry": {"kind": "helix", "radius": 0.02, "pitch": 0.9 * 2 * r,
                                    "turns": 2.0},
                       "stiffness": {"EA": 1e5, "GAy": 1e5, "GAz": 1e5, "GJ": 0.5,
                                     "EIy": 0.5, "EIz": 0.5},
                       "inertia": {"rhoA": 1.0, "rhoJ": 1e-6, "rhoIy": 1e-6,
                                   "rhoIz": 1e-6}}],
             "constraints": [{"kind": "clamp", "rod": "coil", "node": 0}],
             "loads": [{"kind": "force", "rod": "coil", "node": -1,
                        "vector": [0.0, 0.0, -0.01]}],
             "contact": {"radius": r, "self": True, "max_pairs": 64, "quadrature_points": 2,
                         "stiffness": 1e6}}
    result = sj.run(scene)
    assert result.converged, result.message
    rods = result.contacts["rods"]
    p = result.positions("coil")
    separation = np.linalg.norm(p[8:] - p[:9], axis=1)      # one turn apart, same angle
    pen = float(rods["max_penetration"])
    assert 0.0 < pen < 0.05 * 2 * r
    assert np.all(separation >= 2 * r - pen - 1e-12)
    assert np.all(separation <= 2 * r)
    np.testing.assert_allclose(rods["force"], 0.0, atol=1e-9 * float(rods["normal_force"]))
    assert result.stability == {"negative_eigenvalues": 0, "stable": True}   # a stable coil


@pytest.mark.parametrize("near_tests", [broad_phase.NEAR_TESTS, 1])
def test_broad_phase_candidates_match_brute_force_whether_or_not_the_finer_tests_fit(
        near_tests, monkeypatch):
    """40 elements of two rods with random spheres in a small box (many overlaps): the
    candidates are exactly the brute-force pairs e < f with overlapping spheres, passing
    the finer test (here: e + f not a multiple of 3) and not neighbours on one rod, both
    when the finer test runs on the overlapping pairs alone and (NEAR_TESTS = 1: more
    overlapping pairs than it allows) on every slot."""
    monkeypatch.setattr(broad_phase, "NEAR_TESTS", near_tests)
    rng = np.random.default_rng(3)
    n = 40
    centre, radius = rng.uniform(0.0, 0.1, (n, 3)), rng.uniform(0.01, 0.02, n)
    rod_of = np.repeat([0, 1], n // 2)
    s0 = np.tile(np.arange(n // 2) * 0.01, 2)
    e, f, active, overflow = jax.jit(
        lambda c, r: broad_phase.candidate_pairs(
            c, r, lambda e, f: (e + f) % 3 != 0, rod_of, jnp.asarray(s0),
            jnp.asarray(s0 + 0.01), 0.015, 400))(jnp.asarray(centre), jnp.asarray(radius))
    assert not overflow
    found = {(int(a), int(b)) for a, b, on in zip(e, f, active) if on}
    expected = {(a, b) for a in range(n) for b in range(a + 1, n)
                if np.sum((centre[a] - centre[b]) ** 2) < (radius[a] + radius[b]) ** 2
                and (a + b) % 3 != 0
                and not (rod_of[a] == rod_of[b] and s0[b] - s0[a] - 0.01 < 0.015)}
    assert found == expected and len(found) > n // 2


def test_pair_tangents_with_few_touching_among_many_candidates_equal_forward_mode():
    """A hairpin of 8-element legs tracked with a motion allowance of half an element
    length (many candidate pairs, of which only those within 2 r touch), its upper leg
    tilted up from the bend by several slopes so that 12, 6, 4 or no pairs touch:
    the rod-rod tangent of :func:`rod_pairs.system` (pairs' blocks inside the chains
    plus the border ``U W U^T``, however many pair tangents it forms) equals
    ``jax.jacfwd`` of :func:`rod_pairs.residual` on the same pairs at the frames
    ``H exp(y)`` (``lie.compose_exp_quadratic``, the chart of the pair terms)."""
    from simsoft_jax.math import lie, linalg
    from simsoft_jax.physics.assembly import rod_end_flags
    n_leg, h = 8, 0.01
    R, p = _hairpin(n_leg, h)
    E = len(p) - 1
    model = hairpin_model(E, h, clamped=False)
    n = len(p)
    radius, stiffness, length = (jnp.asarray(a) for a in (
        model.contact_radius, model.contact_stiffness, model.length))
    ends = jnp.asarray(rod_end_flags(model.structure))
    zero = tuple(jnp.zeros((k, 6, 6)) for k in (n, n - 1, n - 1))

    @jax.jit
    def parts(R, p):
        pairs = rod_pairs.track(model, R, p, 0.5 * h).pairs
        _, blocks, c = rod_pairs.system(model, R, p, jnp.zeros((n, 6)), zero, pairs=pairs)
        U = c.B.reshape(6 * n, -1)
        K = linalg.dense(blocks) + U @ jnp.einsum("anj,njb->ab", c.C, c.B) @ U.T

        def residual(y):
            Ry, py = jax.vmap(lie.compose_exp_quadratic)(R, p, y.reshape(n, 6))
            return rod_pairs.residual(model, Ry, py, pairs=pairs).reshape(-1)

        g = rod_pairs.residual(model, R, p, pairs=pairs)

        def touches(e, f, nodes):   # a nonzero pair residual
            ef = jnp.stack([e, f])
            return jnp.any(rod_contact.pair_residual(
                (R[nodes], p[nodes]), radius[ef], stiffness[ef], length[ef], ends[ef], 2) != 0)

        touching = jnp.sum(jax.vmap(touches)(pairs.e, pairs.f, pairs.nodes) & pairs.active)
        return K, jax.jacfwd(residual)(jnp.zeros(6 * n)), jnp.sum(pairs.active), touching, g

    upper = p[:, 2] > 0.75 * h
    counts = set()
    for slope in (0.0, 0.012, 0.022, 1.0):
        lifted = p + np.outer(upper, [0.0, 0.0, 1.0]) * slope * np.maximum(
            n_leg * h - p[:, 0], 0.0)[:, None]
        K, reference, candidates, touching, g = parts(jnp.asarray(R), jnp.asarray(lifted))
        assert bool(jnp.all(jnp.isfinite(g)))
        counts.add(int(touching))
        assert int(candidates) > int(touching)
        np.testing.assert_allclose(K, reference, rtol=0, atol=1e-10 * float(
            jnp.abs(reference).max()) + 1e-300)
    # the branches: no pair tangent, 4 of them, 16
    assert 0 in counts and any(0 < c <= 4 for c in counts) and 8 < max(counts) <= 16
