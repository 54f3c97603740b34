"""Point loads at nodes (spec S43): dead (world-fixed direction) and follower (section
frame)."""
import jax.numpy as jnp


def force(R, dead, follower, lam, with_dead: bool, with_follower: bool):
    """``-lam f_ext`` (6,) at one node: dead ``[R^T F; R^T M]`` from the world-frame load
    ``dead`` (6,), follower loads ``follower`` (6,) as given (section frame)."""
    r = jnp.zeros(6, R.dtype)
    if with_dead:
        r = r - lam * jnp.concatenate([R.T @ dead[:3], R.T @ dead[3:]])
    if with_follower:
        r = r - lam * follower
    return r
