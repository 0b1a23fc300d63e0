"""What D0 adds: the look-ahead's data (``meta.lookahead_data``) and the counterfactual meta reward
(``meta.baseline='counterfactual'``), options of Algorithm 1's shared cycle (``metapg_jax/strategies/meta.py``).

Algorithm 1's meta reward R_hat(pi') - R_hat(pi) compares a student trained on D0 with one not trained at all, so
it mixes what D0 holds with what any training does: with 125 look-ahead updates it was negative whatever D0 held,
with 10-25 near zero and blind to random vs on-policy D0 (``results/learned/lookahead/``). The counterfactual
baseline pays the look-ahead twice from the same student, normaliser and minibatch keys:

* pi'  = ``lookahead_steps`` updates on the look-ahead's data (``lookahead_data``): 'd0', minibatches from D0
  alone (the paper's), or 'mix', from the replay buffer with D0 in it (the student's own update mix, so that the
  reward is D0's marginal value to the real update);
* pi'' = as many updates on minibatches of the same size from the replay buffer without D0;

and R(D0) = R_hat(pi') - R_hat(pi''), both rolled out deterministically from the same resets (D1's; pi'''s
rollout is stored and counted like D1, as the paired baseline's rollout of pi). Until the buffer holds a
minibatch pi'' has nothing to train on and the meta reward is 0, as the other baselines' before their first
estimate.

'mix' draws uniformly from the buffer's transitions and D0's without writing D0 into the buffer first (a write
would copy the whole buffer inside the program): the real update's buffer, once D0 is stored, is the same set
unless the buffer is full, where D0 has replaced its oldest |D0| transitions (a difference of |D0| / capacity).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from metapg_jax import replay
from metapg_jax.loop import train_updates

LOOKAHEAD_DATA = ("d0", "mix")


def d0_sampler(d0, batch_size: int):
    """Minibatches (uniform, with replacement) from D0 alone: the paper's look-ahead data."""
    n = d0.reward.shape[0]

    def sample(k):
        idx = jax.random.randint(k, (batch_size,), 0, n)
        return jax.tree.map(lambda x: x[idx], d0)

    return sample


def mix_sampler(buffer: replay.ReplayState, d0, batch_size: int):
    """Minibatches (uniform, with replacement) from the buffer's filled part and D0 together."""
    n0 = d0.reward.shape[0]

    def sample(k):
        idx = jax.random.randint(k, (batch_size,), 0, buffer.size + n0)
        from_d0 = idx >= buffer.size
        old = jax.tree.map(lambda x: x[jnp.clip(idx, 0, jnp.maximum(buffer.size - 1, 0))], buffer.data)
        new = jax.tree.map(lambda x: x[jnp.clip(idx - buffer.size, 0, n0 - 1)], d0)
        pick = lambda a, b: jnp.where(from_d0.reshape(-1, *([1] * (b.ndim - 1))), b, a.astype(b.dtype))
        return jax.tree.map(pick, old, new)

    return sample


def lookahead_sampler(data: str, buffer: replay.ReplayState, d0, batch_size: int):
    """The look-ahead's minibatches: ``data`` is ``meta.lookahead_data``."""
    return d0_sampler(d0, batch_size) if data == "d0" else mix_sampler(buffer, d0, batch_size)


def without_d0(learner, student, normalizer, buffer: replay.ReplayState, batch_size: int, key: jax.Array, num: int):
    """pi'': ``num`` updates of a copy of the student on minibatches of the buffer without D0, and whether it could
    train (the buffer holds a minibatch; otherwise its updates ran on an empty buffer and it is not used)."""
    pi2, _ = train_updates(learner, student, normalizer, lambda k: replay.sample(buffer, k, batch_size), key, num)
    return pi2, buffer.size >= batch_size
