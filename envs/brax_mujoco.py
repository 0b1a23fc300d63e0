"""brax's own versions of the five MuJoCo tasks (``source='brax'``, MJX only) under the contract of
``envs/gym_mujoco.py``'s gymnasium tasks, so the registry and the wrappers treat both sources alike.

See /work/shared/DESIGN.md ("Environments") for why they are not the default: their models, time
steps and rewards differ from gymnasium's.
"""

from __future__ import annotations

from typing import Callable, Dict

import jax
import jax.numpy as jnp
from brax import envs as brax_envs
from brax.envs.base import Env, State, Wrapper

import envs
from envs.mujoco_base import without_the_settotalmass_warning

__all__ = ["BraxTaskAdapter", "BRAX_TASKS", "brax_task"]


class BraxTaskAdapter(Wrapper):
    """Brax's own task env (mjx backend) under the contract of ``envs/gym_mujoco.py``.

    Brax's five tasks already take actions in [-1, 1] (its inverted_pendulum
    rescales onto its [-3, 3] ctrlrange itself, the others have ctrlrange
    [-1, 1]) and their ``done`` is already the termination condition without a
    time limit. What this adapter adds: clipping actions to [-1, 1], float32
    reward/done, an empty ``info`` at reset, ``info`` passed through step
    unchanged (brax's inverted_pendulum would otherwise add a ``time_out``
    key), and an ``observation_size`` that is computed once, by tracing.
    """

    def __init__(self, env: Env, name: str):
        super().__init__(env)
        self.brax_name = name
        self.gym_id = None
        self.frame_skip = int(env.unwrapped._n_frames)
        self.dt = float(env.unwrapped.dt)
        self._obs_size_cache = None

    @property
    def observation_size(self) -> int:
        # brax's PipelineEnv runs an eager reset for this; tracing one is
        # enough and much cheaper.
        if self._obs_size_cache is None:
            obs = jax.eval_shape(self.env.reset, jax.random.PRNGKey(0)).obs
            self._obs_size_cache = int(obs.shape[-1])
        return self._obs_size_cache

    def reset(self, rng: jax.Array) -> State:
        state = self.env.reset(rng)
        return state.replace(
            reward=jnp.asarray(state.reward, jnp.float32),
            done=jnp.asarray(state.done, jnp.float32),
            metrics={k: jnp.asarray(v, jnp.float32) for k, v in state.metrics.items()},
            info={},
        )

    def step(self, state: State, action: jax.Array) -> State:
        action = jnp.clip(jnp.asarray(action, jnp.float32), -1.0, 1.0)
        out = self.env.step(state, action)
        return out.replace(
            reward=jnp.asarray(out.reward, jnp.float32),
            done=jnp.asarray(out.done, jnp.float32),
            metrics={k: jnp.asarray(v, jnp.float32) for k, v in out.metrics.items()},
            info=state.info,
        )


def brax_task(name: str) -> Callable[..., Env]:
    """brax's own env ``name`` on MJX under the contract, as a constructor taking its keyword arguments."""

    def make(**overrides) -> Env:
        with without_the_settotalmass_warning():
            env = brax_envs.get_environment(name, backend="mjx", **overrides)
        return BraxTaskAdapter(env, name)

    make.__name__ = f"brax_{name}"
    make.__doc__ = f"brax's own '{name}' env on the mjx backend, adapted to the contract."
    return make


# brax's version of each built-in task that has one, by task name: a view of their specs (envs.TASKS,
# ``brax_name``) for code that builds them directly.
BRAX_TASKS: Dict[str, Callable[..., Env]] = {
    name: brax_task(spec.brax_name) for name, spec in envs.TASKS.items() if spec.brax_name is not None
}
