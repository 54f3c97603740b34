"""simsoft_jax.math.blas_threads: the OpenBLAS thread limit is applied inside the block,
restored after it (also on an error), and leaves the factorization's numbers unchanged."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from simsoft_jax.math.blas_threads import lapack_threads, loaded_openblas


def test_limit_is_applied_in_the_block_and_restored_after_it():
    jax.scipy.linalg.lu_factor(jnp.eye(3))            # loads JAX's LAPACK
    controls = loaded_openblas()
    if not controls:
        pytest.skip("no OpenBLAS loaded in this process")
    before = [c.get() for c in controls]
    with lapack_threads(3):                     # whatever the environment set
        with lapack_threads(1):
            assert [c.get() for c in controls] == [1] * len(controls)
        assert [c.get() for c in controls] == [3] * len(controls)
    assert [c.get() for c in controls] == before
    with pytest.raises(RuntimeError), lapack_threads(1):
        raise RuntimeError("inside")
    assert [c.get() for c in controls] == before


def test_lu_on_one_thread_solves_the_system():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(300, 300)) + 30.0 * np.eye(300)
    b = rng.normal(size=300)
    with lapack_threads(1):
        x = jax.scipy.linalg.lu_solve(jax.scipy.linalg.lu_factor(jnp.asarray(a)), b)
    np.testing.assert_allclose(a @ np.asarray(x), b, atol=1e-10)


def test_count_below_one_is_refused_by_name():
    with pytest.raises(ValueError, match="count"), lapack_threads(0):
        pass
