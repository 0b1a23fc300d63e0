"""Pendulum: a JAX port of gymnasium's ``Pendulum-v1`` (classic_control/pendulum.py).

Same dynamics, reward, reset distribution and observation as gymnasium, with
one documented interface change: the action is in the normalised box [-1, 1]
and is scaled to the torque bound (``max_torque`` = 2), so every task of this
project takes actions in [-1, 1]. Pendulum never terminates; the 200-step time
limit is added by the registry's wrappers. The paper used ``Pendulum-v0``
(same dynamics; docs/algorithm.md, "Deviations from the paper").
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from brax.envs.base import Env, State


def angle_normalize(x: jax.Array) -> jax.Array:
    """Wraps an angle to [-pi, pi), as gymnasium's ``angle_normalize``."""
    return ((x + jnp.pi) % (2 * jnp.pi)) - jnp.pi


class Pendulum(Env):
    """Gymnasium Pendulum-v1 in JAX. ``pipeline_state`` is ``(theta, theta_dot)``."""

    gym_id = "Pendulum-v1"

    def __init__(self, g: float = 10.0, m: float = 1.0, l: float = 1.0,
                 dt: float = 0.05, max_speed: float = 8.0, max_torque: float = 2.0):
        self.g, self.m, self.l, self.dt = g, m, l, dt
        self.max_speed, self.max_torque = max_speed, max_torque

    @staticmethod
    def _obs(q: jax.Array) -> jax.Array:
        theta, theta_dot = q[0], q[1]
        return jnp.stack([jnp.cos(theta), jnp.sin(theta), theta_dot]).astype(jnp.float32)

    def state_from_q(self, theta, theta_dot) -> State:
        """A state at a given (theta, theta_dot); used by tests and cross-checks."""
        q = jnp.asarray([theta, theta_dot], jnp.float32)
        zero = jnp.zeros((), jnp.float32)
        return State(pipeline_state=q, obs=self._obs(q), reward=zero, done=zero)

    def reset(self, rng: jax.Array) -> State:
        high = jnp.asarray([jnp.pi, 1.0], jnp.float32)
        q = jax.random.uniform(rng, (2,), jnp.float32, -high, high)
        zero = jnp.zeros((), jnp.float32)
        return State(pipeline_state=q, obs=self._obs(q), reward=zero, done=zero)

    def step(self, state: State, action: jax.Array) -> State:
        theta, theta_dot = state.pipeline_state[0], state.pipeline_state[1]
        u = jnp.clip(action[0], -1.0, 1.0) * self.max_torque
        costs = angle_normalize(theta) ** 2 + 0.1 * theta_dot**2 + 0.001 * u**2
        new_theta_dot = theta_dot + (
            3.0 * self.g / (2.0 * self.l) * jnp.sin(theta) + 3.0 / (self.m * self.l**2) * u
        ) * self.dt
        new_theta_dot = jnp.clip(new_theta_dot, -self.max_speed, self.max_speed)
        new_theta = theta + new_theta_dot * self.dt
        q = jnp.stack([new_theta, new_theta_dot]).astype(jnp.float32)
        return state.replace(
            pipeline_state=q,
            obs=self._obs(q),
            reward=(-costs).astype(jnp.float32),
            done=jnp.zeros((), jnp.float32),
        )

    @property
    def observation_size(self) -> int:
        return 3

    @property
    def action_size(self) -> int:
        return 1

    @property
    def backend(self) -> str:
        return "jax"
