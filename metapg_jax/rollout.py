"""Rollouts inside ``jit``: ``rollout(env, policy, env_state, carry, key, n)``.

A policy is a pure function ``policy(carry, obs, first, key) -> (action, carry, extras)``:
``first`` is True on the first step of an episode (so OU noise can reset and
parameter noise re-perturb), ``action`` is what the env gets and the buffer
stores (in [-1, 1]), ``extras`` is anything per-step the caller needs (e.g.
the teacher's unclipped Gaussian sample for its log-probability).
"""

from __future__ import annotations

from typing import Any, Callable

import jax
import jax.numpy as jnp
from brax.envs.base import Env, State

from metapg_jax.types import EpisodeStats, Transition

Policy = Callable[[Any, jax.Array, jax.Array, jax.Array], tuple[jax.Array, Any, Any]]


def env_step(env: Env, policy: Policy, env_state: State, carry: Any, key: jax.Array):
    """One step of one env: returns the new env state, carry and the stored transition."""
    first = env_state.info["steps"] == 0
    action, carry, extras = policy(carry, env_state.obs, first, key)
    nstate = env.step(env_state, action)
    transition = Transition(
        obs=env_state.obs,
        action=action,
        reward=nstate.reward,
        next_obs=nstate.info["next_obs"],
        terminated=nstate.info["terminated"],
        truncated=nstate.info["truncated"],
    )
    stats = EpisodeStats(done=nstate.done, episode_return=nstate.info["episode_return"],
                         episode_length=nstate.info["episode_length"])
    return nstate, carry, transition, stats, extras


def rollout(env: Env, policy: Policy, env_state: State, carry: Any, key: jax.Array, num_steps: int):
    """``num_steps`` steps of one env, auto-resetting; episodes continue across calls.

    Returns ``(env_state, carry, transitions, stats, extras)`` with a leading time axis.
    """

    def step(c, k):
        s, pc = c
        s, pc, tr, st, ex = env_step(env, policy, s, pc, k)
        return (s, pc), (tr, st, ex)

    (env_state, carry), (transitions, stats, extras) = jax.lax.scan(
        step, (env_state, carry), jax.random.split(key, num_steps))
    return env_state, carry, transitions, stats, extras


def completed_episode_mean(stats: EpisodeStats) -> tuple[jax.Array, jax.Array]:
    """Mean return of the episodes that ended in ``stats`` (any leading axes) and their count."""
    n = stats.done.sum()
    mean = jnp.where(n > 0, (stats.episode_return * stats.done).sum() / jnp.maximum(n, 1), jnp.nan)
    return mean, n
