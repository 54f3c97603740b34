"""Lie-group generalized-alpha time integration (spec algorithm.md section 4).

Modules: :mod:`.scheme` (settings, state, the scheme's parameters and update formulas),
:mod:`.residual` (dynamic residual and iteration matrix from element kernels),
:mod:`.memory` (what Newton carries between steps: the reused matrix and the predictor),
:mod:`.newton` (one step: modified Newton, its implicit derivative, sub-stepping),
:mod:`.adjoint` (reverse mode of a rollout by the discrete adjoint of its steps),
:mod:`.rollout` (start state, ``simulate`` with its closed-loop control hook, energy),
:mod:`.driver` (host driver in compiled chunks with progress).
"""
from .driver import rollout
from .residual import dynamic_residual, element_inertia
from .rollout import Trajectory, energy, initial_state, simulate
from .scheme import DynamicSettings, State, alpha_parameters

__all__ = ["DynamicSettings", "State", "Trajectory", "alpha_parameters", "dynamic_residual",
           "element_inertia", "energy", "initial_state", "rollout", "simulate"]
