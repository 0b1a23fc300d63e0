"""Training wrappers shared by every task: time limit, auto-reset, episode statistics.

They follow the Brax `Wrapper` interface so Brax tools apply, but differ from
brax's own `EpisodeWrapper`/`AutoResetWrapper` on purpose:

* `terminated` (a true end of the MDP: do not bootstrap) and `truncated` (the
  time limit: bootstrap) are separate flags, as gymnasium reports them;
* auto-reset draws a *fresh* random initial state from a key carried in the
  state (brax's wrapper replays the first initial state of the run forever);
* the true final observation of an ended episode is kept in
  ``info['next_obs']`` so the stored transition bootstraps from the right state.

Keys written into ``state.info`` (all float32 / int32 scalars per env):

``steps``            steps taken in the current episode (0 right after a reset)
``running_return``   undiscounted return of the current episode so far
``terminated``       1.0 when this step ended the episode by the task's rule
``truncated``        1.0 when this step hit the time limit (and did not terminate)
``episode_return``   return of the episode this step belongs to, this step included
``episode_length``   length of the episode this step belongs to, this step included
``next_obs``         the observation this step produced (before any auto-reset)
``reset_key``        PRNG key for the next auto-reset
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from brax.envs.base import Env, State, Wrapper


class EpisodeWrapper(Wrapper):
    """Time limit, terminated/truncated flags and episode statistics."""

    def __init__(self, env: Env, episode_length: int):
        super().__init__(env)
        if episode_length <= 0:
            raise ValueError(f"episode_length must be positive, got {episode_length}")
        self.episode_length = int(episode_length)

    def reset(self, rng: jax.Array) -> State:
        state = self.env.reset(rng)
        zero = jnp.zeros((), jnp.float32)
        info = dict(state.info)
        info.update(
            steps=jnp.zeros((), jnp.int32),
            running_return=zero,
            terminated=zero,
            truncated=zero,
            episode_return=zero,
            episode_length=jnp.zeros((), jnp.int32),
            next_obs=state.obs,
        )
        return state.replace(info=info, done=zero)

    def step(self, state: State, action: jax.Array) -> State:
        return self._after_step(state, self.env.step(state, action))

    def step_with_reset(self, state: State, action: jax.Array, reset_rng: jax.Array) -> tuple[State, State]:
        """``(step(state, action), reset(reset_rng))``, the auto-reset wrapper's two calls.

        An env with ``fused_autoreset`` (MuJoCo's C engine) does both in one host call, and only
        for the envs whose episode ends (by its rule, or by this time limit, passed as
        ``force_reset``); ``fresh`` then carries only ``pipeline_state`` and ``obs``, all that the
        auto-reset reads of it.
        """
        if getattr(self.env, "fused_autoreset", False):
            force = state.info["steps"] + 1 >= self.episode_length
            nstate, fresh = self.env.step_with_reset(state, action, reset_rng, force)
            return self._after_step(state, nstate), fresh
        return self.step(state, action), self.reset(reset_rng)

    def _after_step(self, state: State, nstate: State) -> State:
        steps = state.info["steps"] + 1
        terminated = nstate.done.astype(jnp.float32)
        truncated = jnp.where(steps >= self.episode_length, 1.0 - terminated, 0.0)
        ret = state.info["running_return"] + nstate.reward
        info = dict(nstate.info)
        info.update(
            steps=steps,
            running_return=ret,
            terminated=terminated,
            truncated=truncated.astype(jnp.float32),
            episode_return=ret,
            episode_length=steps,
            next_obs=nstate.obs,
        )
        done = jnp.maximum(terminated, truncated).astype(jnp.float32)
        return nstate.replace(info=info, done=done)


class AutoResetWrapper(Wrapper):
    """Starts a fresh random episode when one ends; keeps the final observation.

    After a step that ends an episode, ``state.obs`` is the first observation of
    the new episode (what the policy acts on next) while ``info['next_obs']``,
    the flags and the episode statistics still describe the step that ended.
    """

    def reset(self, rng: jax.Array) -> State:
        reset_key, rng = jax.random.split(rng)
        state = self.env.reset(rng)
        info = dict(state.info)
        info["reset_key"] = reset_key
        return state.replace(info=info)

    def step(self, state: State, action: jax.Array) -> State:
        key, reset_rng = jax.random.split(state.info["reset_key"])
        if isinstance(self.env, EpisodeWrapper):
            nstate, fresh = self.env.step_with_reset(state, action, reset_rng)
        else:
            nstate, fresh = self.env.step(state, action), self.env.reset(reset_rng)
        done = nstate.done > 0.5

        # Written for one env (``done`` is a scalar); callers vmap.
        def pick(new, old):
            return jnp.where(done, new, old)

        pipeline_state = jax.tree.map(pick, fresh.pipeline_state, nstate.pipeline_state)
        obs = pick(fresh.obs, nstate.obs)
        info = dict(nstate.info)
        # The running counters restart; the reported flags and statistics of
        # the ended step stay as they are.
        info["steps"] = jnp.where(done, 0, nstate.info["steps"])
        info["running_return"] = jnp.where(done, 0.0, nstate.info["running_return"])
        info["reset_key"] = key
        return nstate.replace(pipeline_state=pipeline_state, obs=obs, info=info)
