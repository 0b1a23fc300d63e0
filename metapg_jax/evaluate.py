"""Evaluation episodes for reporting.

``evaluate`` runs ``num_episodes`` full episodes of a policy (the student's deterministic one; or, with
``stochastic``, a policy that draws its actions, e.g. the random policy of ``experiments.normalisation``)
from fresh resets in parallel envs and returns their returns. Nothing here is
stored in the replay buffer or counted toward the sample budget. The loop is a
``lax.while_loop`` that stops as soon as every episode has ended (under
``vmap`` over seeds: when every seed's episodes have), so evaluations of
policies that fall over early are cheap.
"""

from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jnp
from brax.envs.base import Env

from envs.wrappers import AutoResetWrapper


def evaluate(env: Env, act: Callable[..., jax.Array], key: jax.Array,
             num_episodes: int, max_steps: int, stochastic: bool = False) -> tuple[jax.Array, jax.Array]:
    """Returns (episode returns, episode lengths), each of shape (num_episodes,).

    Args:
      env: a task from ``envs.make`` (auto-reset is bypassed: each episode runs once).
      act: deterministic policy for one raw observation -> action in [-1, 1]; with ``stochastic``,
        ``act(obs, key)`` with a fresh key per episode and step (e.g. the uniformly random policy whose
        returns anchor the normalised scores: ``experiments.normalisation``).
      max_steps: the time limit (episodes end by then through the wrapper anyway).
    """
    if isinstance(env, AutoResetWrapper):
        env = env.env
    if stochastic:
        key, k_act = jax.random.split(key)
        batch_act = lambda obs, t: jax.vmap(act)(obs, jax.random.split(jax.random.fold_in(k_act, t), num_episodes))
    else:
        batch_act = lambda obs, t: jax.vmap(act)(obs)
    state = jax.vmap(env.reset)(jax.random.split(key, num_episodes))
    step = jax.vmap(env.step)

    def cond(c):
        t, _, _, _, done = c
        return jnp.logical_and(t < max_steps, jnp.logical_not(jnp.all(done)))

    def body(c):
        t, s, ret, length, done = c
        s = step(s, batch_act(s.obs, t))
        alive = jnp.logical_not(done)
        ret = ret + jnp.where(alive, s.reward, 0.0)
        length = length + alive.astype(jnp.int32)
        done = jnp.logical_or(done, s.done > 0.5)
        return t + 1, s, ret, length, done

    zeros = jnp.zeros((num_episodes,), jnp.float32)
    init = (jnp.zeros((), jnp.int32), state, zeros, jnp.zeros((num_episodes,), jnp.int32),
            jnp.zeros((num_episodes,), bool))
    _, _, ret, length, _ = jax.lax.while_loop(cond, body, init)
    return ret, length
