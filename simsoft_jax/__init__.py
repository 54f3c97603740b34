"""simsoft_jax: differentiable geometrically exact Cosserat rods on SE(3) in JAX.

The model of Grazioso, Di Gironimo & Siciliano (2019): two-node helical finite elements
on SE(3) with all six strains, static equilibrium by Newton on the Lie group, gradients
by the implicit function theorem.

Importing the package turns on JAX's float64 mode (``jax_enable_x64``): the solvers need
double precision, and every array the package creates is float64. The import itself is
light (no JAX): the public names below are loaded on first use (PEP 562), so that reading
and checking a scene (``simsoft-jax validate``) does not pay JAX's import. Float64 holds
whatever the import order: with JAX already imported its config is updated, otherwise
``JAX_ENABLE_X64=1`` is set for the JAX import to come.

Typical use::

    import simsoft_jax as sj
    scene = sj.load_scene("scene.toml")     # or sj.Scene.from_dict(d)
    result = sj.run(scene)
    result.positions("arm")                 # (nodes, 3)

For gradients and sweeps work with the Model directly::

    model = sj.build_model(scene)
    eq = sj.solve_static(model)             # jit-compiled, vmap- and grad-able
    traj = sj.simulate(model, sj.DynamicSettings(dt=0.01, steps=300))

The Model is the one pytree every solver reads (stiffness, inertia, loads and time laws,
drives, initial velocities); replacing any of its arrays never recompiles.
"""
import importlib as _importlib
import os as _os
import sys as _sys

if "jax" in _sys.modules:
    _sys.modules["jax"].config.update("jax_enable_x64", True)
else:  # read by JAX when it is imported (by the first solver module used)
    _os.environ["JAX_ENABLE_X64"] = "1"

# public name -> the module that defines it (loaded on first use)
_PUBLIC = {
    "leaf_actuation": "studies.actuation",
    **dict.fromkeys(("DynamicSettings", "State", "Trajectory", "energy", "initial_state",
                     "simulate"), "solvers.dynamics"),
    **dict.fromkeys(("InverseResult", "solve_inverse"), "studies.inverse"),
    **dict.fromkeys(("TrackingResult", "track_path"), "studies.inverse_dynamics"),
    "LoadChannels": "model.loads",
    **dict.fromkeys(("BUILTIN_MATERIALS", "Material", "get_material"), "scene.materials"),
    **dict.fromkeys(("Model", "Structure", "build_model"), "model.model"),
    **dict.fromkeys(("Result", "run"), "pipeline.results"),
    **dict.fromkeys(("Scene", "load_scene", "save_scene"), "scene.scene"),
    **dict.fromkeys(("Section", "circle", "custom_inertia", "custom_stiffness",
                     "inertia_diagonal", "rectangle", "semicircle", "stiffness_diagonal",
                     "tube", "viscosity_diagonal"), "scene.sections"),
    **dict.fromkeys(("Equilibrium", "StaticSettings", "solve_static"), "solvers.statics"),
    **dict.fromkeys(("SolveError", "Status"), "solvers.status"),
}
__all__ = sorted(_PUBLIC)
# the layers, where a submodule is looked for by its short name (``sj.statics``)
_LAYERS = ("math", "scene", "model", "physics", "couplings", "solvers", "analysis",
           "studies", "pipeline", "apps")
__version__ = "0.1.0"


def __getattr__(name: str):
    """A public name (:data:`__all__`) or a submodule (``sj.princeton``), imported on
    first use and kept in the package's namespace."""
    if name in _PUBLIC:
        value = getattr(_importlib.import_module(f".{_PUBLIC[name]}", __name__), name)
    elif not name.startswith("__"):
        places = ("",) if name in _LAYERS else (*(f"{layer}." for layer in _LAYERS), "")
        for place in places:
            try:
                value = _importlib.import_module(f".{place}{name}", __name__)
                break
            except ModuleNotFoundError as err:
                if err.name != f"{__name__}.{place}{name}":
                    raise
        else:
            raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_PUBLIC))
