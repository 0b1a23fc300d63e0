"""The replay buffer (metapg_jax/replay.py): a ring that wraps, samples only its filled part, and its size."""

import jax
import jax.numpy as jnp
import numpy as np

from metapg_jax import replay
from metapg_jax.types import Transition


def test_replay_ring_buffer_wraps_and_samples_filled_part():
    buf = replay.init(5, 2, 1)
    mk = lambda start, n: Transition(obs=jnp.arange(start, start + n, dtype=jnp.float32)[:, None].repeat(2, 1),
                                     action=jnp.zeros((n, 1)), reward=jnp.arange(start, start + n, dtype=jnp.float32),
                                     next_obs=jnp.zeros((n, 2)), terminated=jnp.zeros(n), truncated=jnp.zeros(n))
    buf = replay.add(buf, mk(0, 3))
    assert int(buf.size) == 3 and int(buf.ptr) == 3
    s = replay.sample(buf, jax.random.PRNGKey(0), 100)
    assert set(np.asarray(s.reward).tolist()) <= {0.0, 1.0, 2.0}
    buf = replay.add(buf, mk(3, 4))  # wraps: 3, 4 then 5, 6 overwrite slots 0, 1
    assert int(buf.size) == 5 and int(buf.ptr) == 2
    np.testing.assert_array_equal(buf.data.reward, [5, 6, 2, 3, 4])
    assert replay.nbytes(buf) == 5 * (2 + 1 + 1 + 2 + 1 + 1) * 4
