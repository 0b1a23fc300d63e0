"""The running observation normaliser (metapg_jax/normalizer.py)."""

import jax.numpy as jnp
import numpy as np

from metapg_jax import normalizer as norm_lib


def test_normalizer_matches_numpy_and_clips():
    x = np.random.default_rng(0).normal(3.0, 2.0, size=(1000, 2)).astype(np.float32)
    st = norm_lib.update(norm_lib.init(2), jnp.asarray(x))
    mean, std = norm_lib.mean_std(st)
    np.testing.assert_allclose(mean, x.mean(0), rtol=1e-3)
    np.testing.assert_allclose(std, x.std(0), rtol=1e-3)
    assert float(norm_lib.normalize(st, jnp.array([1e3, -1e3]), 5.0).max()) == 5.0
