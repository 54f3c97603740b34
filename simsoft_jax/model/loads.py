"""Time laws of loads: each scene load with a non-constant profile is a *channel*
``pattern * scale(t)`` of the Model (loads with a constant profile are the Model's plain
load arrays); :func:`loads_at` adds the channels at time t to those arrays, and
:func:`full_loads` at full scale (statics).

Profiles (scene-format.md): constant 1; ramp ``clip((t - t0)/(t1 - t0), 0, 1)``;
smoothstep the same passed through ``3x^2 - 2x^3`` (zero slope at both ends); linear
``rate * t`` (the paper's f(t) = c t); table: linear interpolation of (t, scale), held
constant outside the samples. Kinds are static (one compiled branch per channel), all
numbers are arrays, so new load values or time laws never recompile.
"""
from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from ..physics import obstacles
from .parts import refuse_absent
from ..physics.terms import registry


@dataclasses.dataclass(frozen=True)
class LoadChannels:
    """K load channels. kinds: static tuple of profile kinds. params (K,3): t0, t1, rate.
    table_t, table_scale (K, S): padded tables. Patterns: nodal_dead (K,N,6) world,
    nodal_follower (K,N,6) local, distributed_world / distributed_local (K,E,3),
    element_point_dead / element_point_follower (K,E,6) point loads inside elements (at
    the Model's ``element_point_xi``); each None when the Model's array of that name is
    (the scene has no load of that kind, :mod:`simsoft_jax.model.parts`)."""
    kinds: tuple
    params: jax.Array
    table_t: jax.Array
    table_scale: jax.Array
    nodal_dead: jax.Array
    nodal_follower: jax.Array
    distributed_world: jax.Array
    distributed_local: jax.Array
    element_point_dead: jax.Array
    element_point_follower: jax.Array

    def replace(self, **changes) -> "LoadChannels":
        """A copy with some arrays replaced (same kinds: no recompilation); a pattern of
        a load kind the model was built without (None) is refused, naming it
        (:func:`~simsoft_jax.model.parts.refuse_absent`)."""
        refuse_absent(self, changes)
        return dataclasses.replace(self, **changes)


# The load arrays a channel carries a pattern of (Model fields of the same names).
CHANNEL_PATTERNS = ("nodal_dead", "nodal_follower", "distributed_world", "distributed_local",
                    "element_point_dead", "element_point_follower")

jax.tree_util.register_dataclass(
    LoadChannels, data_fields=["params", "table_t", "table_scale", *CHANNEL_PATTERNS],
    meta_fields=["kinds"])


def profile_scale(kind: str, params, table_t, table_scale, t):
    """Scale factor of one channel at time ``t`` (s)."""
    t0, t1, rate = params[0], params[1], params[2]
    if kind == "constant":
        return jnp.ones_like(t)
    if kind == "linear":
        return rate * t
    if kind == "table":
        return jnp.interp(t, table_t, table_scale)
    x = jnp.clip((t - t0) / (t1 - t0), 0.0, 1.0)
    if kind == "ramp":
        return x
    if kind == "smoothstep":
        return x * x * (3.0 - 2.0 * x)
    raise ValueError(f"profile.kind: unknown kind {kind!r}")


def law_scales(kinds, params, table_t, table_scale, t):
    """Scale factors (K,) at time ``t`` of K time laws: ``kinds`` (static tuple),
    ``params`` (K,3), ``table_t``, ``table_scale`` (K,S) (see :func:`profile_tables`)."""
    return jnp.stack([profile_scale(k, params[i], table_t[i], table_scale[i], t)
                      for i, k in enumerate(kinds)]) if kinds else jnp.zeros(0)


def scales(channels: LoadChannels, t):
    """Scale factors (K,) of all channels at time ``t``."""
    return law_scales(channels.kinds, channels.params, channels.table_t,
                      channels.table_scale, t)


def _with_channels(model, s):
    """``model`` with each channel's pattern times ``s`` (K,) added to its load arrays
    (those the model has)."""
    ch = model.channels
    if not ch.kinds:
        return model
    return model.replace(**{
        key: getattr(model, key) + jnp.tensordot(s, getattr(ch, key), axes=1)
        for key in CHANNEL_PATTERNS if getattr(model, key) is not None})


@dataclasses.dataclass(frozen=True)
class TimeLaws:
    """K time laws of actuators (tendon tensions, chamber pressures): ``kinds`` static
    tuple of profile kinds, ``params`` (K,3), ``table_t``, ``table_scale`` (K,S)
    (:func:`profile_tables`)."""
    kinds: tuple
    params: jax.Array
    table_t: jax.Array
    table_scale: jax.Array

    def scales(self, t):
        """Scale factors (K,) at time ``t`` (s)."""
        return law_scales(self.kinds, self.params, self.table_t, self.table_scale, t)


jax.tree_util.register_dataclass(TimeLaws, data_fields=["params", "table_t", "table_scale"],
                                 meta_fields=["kinds"])


def build_laws(profiles) -> TimeLaws:
    """:class:`TimeLaws` of a list of ProfileSpec (NumPy float64 leaves)."""
    return TimeLaws(tuple(p.kind for p in profiles),
                    *(np.asarray(a, np.float64) for a in profile_tables(profiles)))


def obstacles_at(model, t):
    """Parameter rows (K,ROW) and velocities (K,3) m/s of the obstacles at time ``t`` (s):
    obstacle k moved rigidly by ``shift_k scale_k(t)`` (``model.obstacle_shift``, its time
    law ``model.obstacle_law``), its velocity ``shift_k dscale_k/dt`` (autodiff in t)."""
    s = model.structure
    law = model.obstacle_law
    scale, rate = jax.jvp(law.scales, (t,), (jnp.ones_like(t),))
    rows = jnp.stack([obstacles.translate(kind, model.obstacles[k],
                                          model.obstacle_shift[k] * scale[k])
                      for k, kind in enumerate(s.obstacle_kinds)])
    return rows, model.obstacle_shift * rate[:, None]


def loads_at(model, t):
    """``model`` with its load arrays holding the total loads at time ``t`` (s): the
    constant ones plus every channel at its scale ``scale_k(t)``; the registered terms'
    time laws (tendon tensions, chamber pressures, the magnetic field;
    :func:`~simsoft_jax.physics.terms.registry.at_time`); moving obstacles where they are at ``t``
    (:func:`obstacles_at`)."""
    model = _with_channels(model, scales(model.channels, t))
    changes = registry.at_time(model, t)
    if model.obstacle_shift is not None:
        changes["obstacles"], changes["obstacle_velocity"] = obstacles_at(model, t)
    return model.replace(**changes) if changes else model


def full_loads(model):
    """``model`` with its load arrays holding every load at full scale (each channel's
    pattern once), as statics applies them."""
    return _with_channels(model, jnp.ones(len(model.channels.kinds)))


def profile_tables(profiles):
    """Arrays of K time laws (:class:`~simsoft_jax.scene.scene_specs.ProfileSpec`): params
    (K,3) ``t0, t1, rate`` and tables ``table_t``, ``table_scale`` (K,S) padded with
    increasing times beyond the last sample, holding the last value (NumPy)."""
    k = len(profiles)
    params = np.tile([0.0, 1.0, 0.0], (k, 1))
    width = max([2] + [len(p.t) for p in profiles if p.kind == "table"])
    table_t = np.tile(np.arange(width, dtype=float), (k, 1))
    table_scale = np.zeros((k, width))
    for i, prof in enumerate(profiles):
        if prof.kind in ("ramp", "smoothstep"):
            params[i, :2] = prof.t0, prof.t1
        elif prof.kind == "linear":
            params[i, 2] = prof.rate
        elif prof.kind == "table":
            m = len(prof.t)
            table_t[i] = np.concatenate([prof.t, prof.t[-1] + 1.0 + np.arange(width - m)])
            table_scale[i] = np.concatenate([prof.scale, np.full(width - m, prof.scale[-1])])
    return params, table_t, table_scale


def build_channels(loads, structure, present: dict) -> LoadChannels:
    """One channel per load spec in ``loads``, with its pattern at unit scale (NumPy
    float64 leaves); a pattern is None where ``present[field]`` is False (the Model's
    load array of that kind is None: the scene has no load of that kind)."""
    n, e = structure.n_nodes, structure.n_elements
    k = len(loads)
    rods = {r.name: r for r in structure.rods}
    dead, follower = np.zeros((k, n, 6)), np.zeros((k, n, 6))
    dist_world, dist_local = np.zeros((k, e, 3)), np.zeros((k, e, 3))
    point_dead, point_follower = np.zeros((k, e, 6)), np.zeros((k, e, 6))
    params, table_t, table_scale = profile_tables([ld.profile for ld in loads])
    for i, load in enumerate(loads):
        info = rods[load.rod]
        if load.kind == "distributed_force":
            target = dist_world if load.frame == "world" else dist_local
            target[i, info.first_element:info.first_element + info.elements] = load.vector
        elif load.element is not None:
            target = point_dead if load.frame == "world" else point_follower
            cols = slice(0, 3) if load.kind == "force" else slice(3, 6)
            target[i, info.first_element + load.element, cols] = load.vector
        else:
            target = dead if load.frame == "world" else follower
            cols = slice(0, 3) if load.kind == "force" else slice(3, 6)
            target[i, info.first_node + load.node, cols] = load.vector
    patterns = dict(nodal_dead=dead, nodal_follower=follower, distributed_world=dist_world,
                    distributed_local=dist_local, element_point_dead=point_dead,
                    element_point_follower=point_follower)
    return LoadChannels(tuple(ld.profile.kind for ld in loads), params, table_t, table_scale,
                        **{k: a if present[k] else None for k, a in patterns.items()})
