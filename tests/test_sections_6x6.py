"""Full 6x6 section stiffness (``stiffness = { matrix = ... }``) and saving scenes built
with NumPy values."""
import numpy as np
import pytest

from simsoft_jax.scene.scene import Scene, load_scene, save_scene


def numpy_scene():
    """A scene dictionary holding NumPy scalars (np.float64, np.int64, np.str_, np.bool_)
    and arrays, as one builds it in Python."""
    return {
        "name": np.str_("numpy_built"),
        "solver": {"kind": "static", "tolerance": np.float64(1e-9),
                   "load_steps": np.int64(3)},
        "gravity": {"vector": np.array([0.0, 0.0, -9.81])},
        "rods": [{"name": "arm", "material": "aluminum_7075",
                  "section": {"shape": "rectangle", "width": np.float64(0.4712345678901234),
                              "height": np.float32(0.25)},
                  "elements": np.int32(4),
                  "geometry": {"kind": "straight", "length": np.float64(2.0)},
                  "base": {"position": np.zeros(3), "rotation": np.array([0.1, 0.0, 0.0])}}],
        "constraints": [{"kind": "clamp", "rod": "arm", "node": np.int64(0)}],
        "loads": [{"kind": "force", "rod": "arm", "node": np.int64(-1),
                   "vector": np.array([0.0, np.float64(1.5), -2.0]),
                   "profile": {"kind": "table", "t": np.linspace(0.0, 1.0, 3),
                               "scale": [np.float64(0.0), 0.5, np.float16(1.0)]}}],
    }


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_save_scene_round_trips_numpy_values(tmp_path, suffix):
    scene = Scene.from_dict(numpy_scene())
    raw = scene.to_dict()
    # only plain Python types survive validation (np.float64 is a float subclass)
    stack = [raw]
    while stack:
        item = stack.pop()
        if isinstance(item, dict):
            stack.extend(item.values())
        elif isinstance(item, list):
            stack.extend(item)
        else:
            assert type(item) in (str, int, float, bool), (type(item), item)
    path = tmp_path / f"scene{suffix}"
    save_scene(scene, path)
    text = path.read_text()
    assert "np." not in text and "array(" not in text
    again = load_scene(path)
    assert again.to_dict() == raw
    assert again.replace(source=None) == scene
    assert raw["rods"][0]["section"]["width"] == 0.4712345678901234   # exact round trip
    assert raw["rods"][0]["elements"] == 4 and raw["name"] == "numpy_built"


# ----------------------------------------------------------------------------- 6x6 sections
import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

import simsoft_jax as sj  # noqa: E402
from simsoft_jax.physics import assembly  # noqa: E402
from simsoft_jax.math import lie, linalg  # noqa: E402
from simsoft_jax.model import loads  # noqa: E402
from simsoft_jax.scene import sections  # noqa: E402

from conftest import iteration_matrices  # noqa: E402

DIAG = {"EA": 2e3, "GAy": 1e3, "GAz": 1.5e3, "GJ": 0.8, "EIy": 1.0, "EIz": 1.7}
INERTIA = {"rhoA": 0.2, "rhoJ": 2e-3, "rhoIy": 1e-3, "rhoIz": 1.5e-3}


def coupled_matrix():
    """A dense SPD 6x6 with every kind of coupling (extension-shear, extension-twist,
    bending-twist, shear-bending), ordered like the strains."""
    K = np.diag([DIAG[k] for k in ("EA", "GAy", "GAz", "GJ", "EIy", "EIz")])
    rng = np.random.default_rng(7)
    C = rng.uniform(-0.3, 0.3, (6, 6))
    C = 0.5 * (C + C.T)
    np.fill_diagonal(C, 1.0)
    root = np.sqrt(np.diag(K))
    return C * np.outer(root, root)


def scene(stiffness, kind="static", loads_=None, elements=4, geometry=None):
    rod = {"name": "arm", "elements": elements, "stiffness": stiffness, "inertia": INERTIA,
           "geometry": geometry or {"kind": "arc", "radius": 1.5, "angle_deg": 30}}
    d = {"solver": {"kind": "static", "tolerance": 1e-13}, "rods": [rod],
         "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}],
         "loads": loads_ if loads_ is not None else [
             {"kind": "force", "rod": "arm", "node": -1, "vector": [0.0, 0.2, -0.3]},
             {"kind": "moment", "rod": "arm", "node": 2, "vector": [0.02, 0.0, 0.01],
              "frame": "local"},
             {"kind": "distributed_force", "rod": "arm", "vector": [0.0, 0.05, 0.0]},
             {"kind": "distributed_force", "rod": "arm", "vector": [0.0, 0.0, 0.04],
              "frame": "local"}],
         "gravity": {"vector": [0.0, 0.0, -9.81]}}
    if kind == "dynamic":
        d["solver"] = {"kind": "dynamic", "t_end": 0.02, "dt": 0.01}
    return d


def matrix_key(K):
    return {"matrix": np.asarray(K).tolist()}


@pytest.mark.parametrize("K, message", [
    (np.diag([1.0, 2, 3, 4, 5, 6]) + np.eye(6, k=1) * 0.1, "must be symmetric"),
    (np.diag([1.0, 2, 3, -4, 5, 6]), "must be positive definite"),
    (np.array([[1.0, 2.0], [2.0, 1.0]]), "must have 6 entries"),
    (np.diag([1.0, 2, 3, 4, 5]), "must have 6 entries"),
])
def test_matrix_validated_at_load_time(K, message):
    if K.shape == (5, 5):
        K = np.pad(K, ((0, 1), (0, 0)))[:, :5]   # 6 rows of 5 numbers
    with pytest.raises(ValueError, match=r"rods\[0\]\.stiffness\.matrix(\[0\])?: .*" + message):
        sj.Scene.from_dict(scene(matrix_key(K)))


def test_matrix_key_rejects_mixing_and_short_matrices():
    with pytest.raises(ValueError, match=r"rods\[0\]\.stiffness\.EA: unknown key"):
        sj.Scene.from_dict(scene({"matrix": np.eye(6).tolist(), "EA": 1.0}))
    with pytest.raises(ValueError, match=r"rods\[0\]\.stiffness\.matrix: must have 6 rows"):
        sj.Scene.from_dict(scene({"matrix": np.eye(6)[:5].tolist()}))
    # a positive semi-definite matrix (a rigid mode of the section) is rejected too
    K = np.diag([1.0, 2, 3, 4, 5, 6])
    K[3, 4] = K[4, 3] = np.sqrt(4 * 5)
    with pytest.raises(ValueError, match="positive definite"):
        sj.Scene.from_dict(scene(matrix_key(K)))


def test_diagonal_matrix_is_bitwise_the_diagonal_path():
    K = np.diag([DIAG[k] for k in ("EA", "GAy", "GAz", "GJ", "EIy", "EIz")])
    m_diag = sj.build_model(sj.Scene.from_dict(scene(DIAG)))
    m_mat = sj.build_model(sj.Scene.from_dict(scene(matrix_key(K))))
    assert not m_mat.structure.coupled_stiffness and m_mat.stiffness.shape == (4, 6)
    assert m_mat.structure == m_diag.structure
    a, b = sj.solve_static(m_diag), sj.solve_static(m_mat)
    assert bool(a.converged) and bool(b.converged)
    assert np.array_equal(np.asarray(a.p), np.asarray(b.p))
    assert np.array_equal(np.asarray(a.R), np.asarray(b.R))


def deformed(model, seed, size=0.05):
    x = size * np.random.default_rng(seed).standard_normal((model.structure.n_nodes, 6))
    return jax.vmap(lie.compose_exp)(model.R0, model.p0, jnp.asarray(x))


def test_coupled_static_tangent_paths_agree_with_jacfwd():
    loads_ = [{"kind": "force", "rod": "arm", "node": -1, "vector": [0.0, 0.2, -0.3]}]
    model = sj.build_model(sj.Scene.from_dict(scene(matrix_key(coupled_matrix()), loads_=loads_)))
    assert model.structure.coupled_stiffness and model.stiffness.shape == (4, 6, 6)
    R, p = deformed(model, 0)
    tangent = jax.jit(assembly.residual_and_tangent, static_argnums=4)
    (r1, b1), (r2, b2) = (tangent(model, R, p, 0.7, t) for t in ("closed_form", "autodiff"))
    K1, K2 = np.asarray(linalg.dense(b1)), np.asarray(linalg.dense(b2))
    np.testing.assert_allclose(np.asarray(r1), np.asarray(r2), rtol=0, atol=1e-12)
    np.testing.assert_allclose(K1, K2, rtol=0, atol=1e-10 * np.abs(K1).max())
    assert np.abs(K1 - K1.T).max() > 1e-3 * np.abs(K1).max()   # away from equilibrium


@pytest.mark.slow
def test_coupled_dynamic_iteration_matrix_paths_agree():
    model = loads.loads_at(sj.build_model(sj.Scene.from_dict(
        scene(matrix_key(coupled_matrix()), kind="dynamic"))), 0.0)
    (r1, S1), (r2, S2) = iteration_matrices(model, *deformed(model, 1))
    np.testing.assert_allclose(r1, r2, rtol=0, atol=1e-10)
    np.testing.assert_allclose(S1, S2, rtol=0, atol=1e-10 * np.abs(S1).max())


def test_coupled_elastic_force_is_the_gradient_of_the_strain_energy():
    """Path independence: the elastic nodal forces are the gradient, in the right
    perturbations of the nodal frames, of ``sum (L/2) eps^T K eps`` written here from the
    relative pose directly (no strain map); so the work of the elastic forces along any
    path depends on its ends only."""
    d = scene(matrix_key(coupled_matrix()), loads_=[])
    del d["gravity"]
    model = sj.build_model(sj.Scene.from_dict(d))
    K = np.asarray(model.stiffness)
    R, p = deformed(model, 2, 0.2)
    a = np.asarray(model.structure.element_nodes)

    def energy(x):
        Rx, px = jax.vmap(lie.compose_exp)(R, p, x)
        total = 0.0
        for e, n in enumerate(a):
            d = lie.log_se3(lie.relative_pose(Rx[n], px[n], Rx[n + 1], px[n + 1]))
            eps = (d - model.d0[e]) / model.length[e]
            total = total + 0.5 * model.length[e] * eps @ (K[e] @ eps)
        return total

    grad = np.asarray(jax.jit(jax.grad(energy))(jnp.zeros((model.structure.n_nodes, 6))))
    forces = np.asarray(jax.jit(assembly.residual)(model, R, p, 1.0))
    free = np.asarray(model.structure.free_mask())
    np.testing.assert_allclose(forces, grad * free, rtol=0, atol=1e-10 * np.abs(grad).max())


def test_coupled_tangent_symmetric_at_equilibrium():
    """Conservative loads (dead tip force, gravity): at equilibrium the tangent on the free
    dofs is the Hessian of the total potential, hence symmetric."""
    loads_ = [{"kind": "force", "rod": "arm", "node": -1, "vector": [0.0, 0.4, -0.6]}]
    d = scene(matrix_key(coupled_matrix()), loads_=loads_)
    del d["gravity"]          # the same structure as the two tests below (one compile)
    model = sj.build_model(sj.Scene.from_dict(d))
    eq = sj.solve_static(model)
    assert bool(eq.converged)
    _, blocks = jax.jit(assembly.residual_and_tangent)(model, eq.R, eq.p)
    Kt = np.asarray(linalg.dense(blocks))
    free = np.asarray(model.structure.free_mask()).ravel() > 0
    Kf = Kt[np.ix_(free, free)]
    np.testing.assert_allclose(Kf, Kf.T, rtol=0, atol=1e-9 * np.abs(Kf).max())


def test_extension_twist_coupling_exact():
    """Extension-twist coupled strip (Minguet-Dugundji beam 3 section) pulled by an axial tip
    force F stays straight with the uniform strain ``eps = K^-1 [F, 0, 0, 0, 0, 0]``: tip
    stretch ``L eps_x`` and twist ``L kappa_x``, exactly (a screw motion)."""
    K = sections.coupled_stiffness([3.9e6, 1.1e6, 1.2e5, 1.18, 0.983, 290.0],
                                   {("eps_x", "kappa_x"): -522.0})
    F, L = 2000.0, 0.55
    loads_ = [{"kind": "force", "rod": "arm", "node": -1, "vector": [F, 0.0, 0.0]}]
    d = scene(matrix_key(K), loads_=loads_, geometry={"kind": "straight", "length": L})
    del d["gravity"]
    model = sj.build_model(sj.Scene.from_dict(d))
    eq = sj.solve_static(model)
    eps = np.linalg.solve(K, [F, 0, 0, 0, 0, 0])
    tip_R, tip_p = np.asarray(eq.R[-1]), np.asarray(eq.p[-1])
    np.testing.assert_allclose(tip_p, [L * (1 + eps[0]), 0, 0], rtol=0, atol=1e-12)
    angle = np.arctan2(tip_R[2, 1], tip_R[1, 1])
    assert abs(L * eps[3]) > 0.05                        # a visible twist, from the coupling
    np.testing.assert_allclose(angle, L * eps[3], rtol=1e-10)


def test_bending_twist_coupling_small_load_linear_theory():
    """Bending-twist coupled strip (Minguet-Dugundji beam 2 section) under a small tip
    moment about local y: the tip rotation tends to ``L K^-1 [0,0,0,0,M,0]`` (linear
    theory), twist included."""
    K = sections.coupled_stiffness([4e6, 2.6e5, 5.5e5, 0.368, 0.522, 298.0],
                                   {(0, 1): -2.7e5, ("kappa_x", "kappa_y"): -0.102})
    M, L = 1e-5, 0.55
    loads_ = [{"kind": "moment", "rod": "arm", "node": -1, "vector": [0.0, M, 0.0]}]
    d = scene(matrix_key(K), loads_=loads_, geometry={"kind": "straight", "length": L})
    del d["gravity"]
    eq = sj.solve_static(sj.build_model(sj.Scene.from_dict(d)))
    expected = L * np.linalg.solve(K, [0, 0, 0, 0, M, 0])[3:]
    rotvec = np.asarray(lie.log_so3(eq.R[-1]))
    np.testing.assert_allclose(rotvec, expected, rtol=1e-4, atol=1e-4 * np.abs(expected).max())
    assert abs(expected[0]) > 0.2 * abs(expected[1])     # twist of the order of the bending


def test_beam4_helper_axis_mapping():
    K4 = np.array([[9.8e6, -0.6, -2.4, 5.4e4], [-0.6, 7.28, 0.107, 0.0168],
                   [-2.4, 0.107, 4.59, -0.113], [5.4e4, 0.0168, -0.113, 3318.0]])
    K = sections.beam4_stiffness(K4, shear=(1e8, 2e8), signs=(1, -1, 1, 1))
    assert K[0, 0] == 9.8e6 and K[3, 3] == 7.28 and K[4, 4] == 4.59 and K[5, 5] == 3318.0
    assert K[1, 1] == 1e8 and K[2, 2] == 2e8
    assert K[0, 5] == K[5, 0] == 5.4e4 and K[3, 4] == -0.107 and K[0, 3] == 0.6
    assert not np.any(K[1:3, [0, 3, 4, 5]])


def _cantilever_tip(K, elements, L=0.55, P=1e-3):
    """Tip deflection (m) along local z of a clamped straight rod with section K under a
    small tip force P (N) along z (linear range: deflection ~ 2e-5 L)."""
    rod = {"name": "arm", "elements": elements, "stiffness": matrix_key(K), "inertia": INERTIA,
           "geometry": {"kind": "straight", "length": L}}
    d = {"solver": {"kind": "static", "tolerance": 1e-13}, "rods": [rod],
         "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}],
         "loads": [{"kind": "force", "rod": "arm", "node": -1, "vector": [0.0, 0.0, P]}]}
    eq = sj.solve_static(sj.build_model(sj.Scene.from_dict(d)))
    assert bool(eq.converged)
    return float(eq.p[-1][2])


def test_beam4_default_shear_is_negligible_timoshenko_cantilever():
    """Closed form: a cantilever's tip deflection is ``P L^3 / (3 EI) + P L / GA``
    (Euler-Bernoulli plus Timoshenko's shear term). With the default shear of
    ``beam4_stiffness`` the shear term is below 1e-7 of the bending term (the earlier default
    GA = 1e3 N added 4.6 % here); with a soft explicit GA the difference of the two tip
    deflections is exactly the shear term (constant shear strain, no discretization
    error), and the Richardson-extrapolated bending term is Euler-Bernoulli's."""
    L, P, EA, EI = 0.55, 1e-3, 1e7, 4.6
    K4 = np.diag([EA, 7.0, EI, 3300.0])
    rigid = sections.beam4_stiffness(K4)
    assert rigid[1, 1] == rigid[2, 2] == sections.RIGID_SHEAR_FACTOR * EA
    bending = P * L**3 / (3 * EI)
    coarse, fine = _cantilever_tip(rigid, 8), _cantilever_tip(rigid, 16)
    extrapolated = (4 * fine - coarse) / 3                   # O(h^2) discretization
    assert extrapolated == pytest.approx(bending + P * L / rigid[2, 2], rel=2e-6)
    assert P * L / rigid[2, 2] < 1e-7 * bending
    soft = _cantilever_tip(sections.beam4_stiffness(K4, shear=(100.0, 100.0)), 16)
    assert soft - fine == pytest.approx(P * L / 100.0 - P * L / rigid[2, 2], rel=1e-6)


def test_beam4_rejects_a_bad_extension_or_shear():
    K4 = np.diag([1e7, 7.0, 4.6, 3300.0])
    with pytest.raises(ValueError, match=r"shear\[1\]"):
        sections.beam4_stiffness(K4, shear=(1e3, 0.0))
    K4[0, 0] = -1.0
    with pytest.raises(ValueError, match=r"K4\[0\]\[0\]"):
        sections.beam4_stiffness(K4)
