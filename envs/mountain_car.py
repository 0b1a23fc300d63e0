"""MountainCarContinuous: a JAX port of gymnasium's ``MountainCarContinuous-v0``
(classic_control/continuous_mountain_car.py).

A car in a valley whose engine is too weak to drive up the right hill directly: it has to swing back and forth
to build up speed. Every step costs 0.1 a^2 for the action a; the step that reaches the goal (position >= 0.45
with velocity >= ``goal_velocity``) earns 100 more and ends the episode. The time limit (gymnasium's 999 steps)
is added by the registry's wrappers. A policy that never finds the goal does best by not moving (return 0), so
the task asks whether exploration reaches a sparse reward at all.

Same dynamics, reward, termination, reset distribution and observation as gymnasium, in gymnasium's order:
the force is the action clipped to [-1, 1] times ``POWER``; the velocity changes by force - 0.0025 cos(3 x) and
is clipped to +-``MAX_SPEED``; the position moves by the new velocity and is clipped to [-1.2, 0.6]; a car at the
left wall moving left stops there; the reward charges the action as given (unclipped, as gymnasium does).
gymnasium's action box is already [-1, 1], so the project's normalised actions need no scaling. The arithmetic
is float32; gymnasium keeps its state in float32 but computes 0.0025 cos(3 x) in float64, so the two agree to
float32 round-off (``tests/test_mountain_car.py`` states how closely, per step and over whole episodes).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from brax.envs.base import Env, State

# gymnasium's constants (Continuous_MountainCarEnv.__init__ and step).
MIN_POSITION, MAX_POSITION = -1.2, 0.6
MAX_SPEED = 0.07
GOAL_POSITION = 0.45
POWER = 0.0015        # velocity change per unit of force
GRAVITY = 0.0025      # the hill's pull: -GRAVITY * cos(3 x)
GOAL_REWARD = 100.0
ACTION_COST = 0.1     # reward -= ACTION_COST * a^2
RESET_LOW, RESET_HIGH = -0.6, -0.4   # the initial position's range (the initial velocity is 0)


class MountainCarContinuous(Env):
    """Gymnasium MountainCarContinuous-v0 in JAX. ``pipeline_state`` is ``(position, velocity)``, which is also
    the observation."""

    gym_id = "MountainCarContinuous-v0"

    def __init__(self, goal_velocity: float = 0.0):
        # gymnasium.make("MountainCarContinuous-v0", goal_velocity=...): the least velocity that counts at the goal.
        self.goal_velocity = goal_velocity

    def state_from_q(self, position, velocity) -> State:
        """A state at a given (position, velocity); used by tests and cross-checks."""
        q = jnp.stack([jnp.asarray(position, jnp.float32), jnp.asarray(velocity, jnp.float32)])
        zero = jnp.zeros((), jnp.float32)
        return State(pipeline_state=q, obs=q, reward=zero, done=zero)

    def reset(self, rng: jax.Array) -> State:
        position = jax.random.uniform(rng, (), jnp.float32, RESET_LOW, RESET_HIGH)
        return self.state_from_q(position, 0.0)

    def step(self, state: State, action: jax.Array) -> State:
        position, velocity = state.pipeline_state[0], state.pipeline_state[1]
        a = action[0].astype(jnp.float32)
        force = jnp.clip(a, -1.0, 1.0)
        velocity = velocity + (force * jnp.float32(POWER) - jnp.float32(GRAVITY) * jnp.cos(3.0 * position))
        velocity = jnp.clip(velocity, -MAX_SPEED, MAX_SPEED)
        position = jnp.clip(position + velocity, MIN_POSITION, MAX_POSITION)
        # The left wall is inelastic: a car that reaches it moving left stops.
        velocity = jnp.where((position == jnp.float32(MIN_POSITION)) & (velocity < 0.0), 0.0, velocity)
        terminated = (position >= jnp.float32(GOAL_POSITION)) & (velocity >= jnp.float32(self.goal_velocity))
        reward = jnp.where(terminated, jnp.float32(GOAL_REWARD), 0.0) - jnp.float32(ACTION_COST) * jnp.square(a)
        q = jnp.stack([position, velocity]).astype(jnp.float32)
        return state.replace(pipeline_state=q, obs=q, reward=reward.astype(jnp.float32),
                             done=terminated.astype(jnp.float32))

    @property
    def observation_size(self) -> int:
        return 2

    @property
    def action_size(self) -> int:
        return 1

    @property
    def backend(self) -> str:
        return "jax"
