"""Point loads at nodes (spec S43): dead (world-fixed direction) and follower (section
frame)."""
import jax.numpy as jnp


def force(R, dead, follower, lam):
    """``-lam f_ext`` (6,) at one node: dead ``[R^T F; R^T M]`` from the world-frame load
    ``dead`` (6,), follower loads ``follower`` (6,) as given (section frame); each None
    when the model has no load of that kind (then not traced)."""
    r = jnp.zeros(6, R.dtype)
    if dead is not None:
        r = r - lam * jnp.concatenate([R.T @ dead[:3], R.T @ dead[3:]])
    if follower is not None:
        r = r - lam * follower
    return r
