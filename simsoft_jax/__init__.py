"""simsoft_jax: differentiable geometrically exact Cosserat rods on SE(3) in JAX.

The model of Grazioso, Di Gironimo & Siciliano (2019): two-node helical finite elements
on SE(3) with all six strains, static equilibrium by Newton on the Lie group, gradients
by the implicit function theorem.

Importing the package turns on JAX's float64 mode (``jax_enable_x64``): the solvers need
double precision, and every array the package creates is float64.

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
import jax as _jax

_jax.config.update("jax_enable_x64", True)

from .actuation import leaf_actuation  # noqa: E402
from .dynamics import (DynamicSettings, State, Trajectory, energy,  # noqa: E402
                       initial_state, simulate)
from .inverse import InverseResult, solve_inverse  # noqa: E402
from .inverse_dynamics import TrackingResult, track_path  # noqa: E402
from .loads import LoadChannels  # noqa: E402
from .materials import BUILTIN_MATERIALS, Material, get_material  # noqa: E402
from .model import Model, Structure, build_model  # noqa: E402
from .results import Result, run  # noqa: E402
from .scene import Scene, load_scene, save_scene  # noqa: E402
from .sections import (Section, circle, custom_inertia, custom_stiffness,  # noqa: E402
                       inertia_diagonal, rectangle, semicircle, stiffness_diagonal, tube,
                       viscosity_diagonal)
from .statics import Equilibrium, StaticSettings, solve_static  # noqa: E402
from .status import SolveError, Status  # noqa: E402

__all__ = [
    "BUILTIN_MATERIALS", "DynamicSettings", "Equilibrium", "InverseResult",
    "LoadChannels", "Material", "Model", "Result", "Scene", "Section", "SolveError",
    "State", "StaticSettings", "Status", "Structure", "TrackingResult", "Trajectory",
    "build_model", "circle", "custom_inertia", "custom_stiffness", "energy",
    "get_material", "inertia_diagonal", "initial_state", "leaf_actuation", "load_scene",
    "rectangle", "run", "save_scene", "semicircle", "simulate", "solve_inverse",
    "solve_static", "stiffness_diagonal", "track_path", "tube", "viscosity_diagonal",
]
__version__ = "0.1.0"
