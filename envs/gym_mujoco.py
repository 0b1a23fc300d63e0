"""gymnasium's v5 MuJoCo tasks behind the Brax ``Env`` interface, on MJX (and, through
``envs/mujoco_c.py``, on MuJoCo's C engine: the task math here serves both).

Reference: the installed gymnasium package (1.x), files
``gymnasium/envs/mujoco/{inverted_pendulum,inverted_double_pendulum,hopper,
half_cheetah,reacher}_v5.py`` and ``mujoco_env.py``. Models are gymnasium's
own XML files, loaded from the installed package's ``assets/`` folder, and
stepped with ``mujoco.mjx`` with gymnasium's frame skip; observation, reward,
termination and reset noise follow the v5 definitions with v5 default kwargs.
See /work/shared/DESIGN.md ("Environments") for why we do not use brax's own
versions of these tasks (different models, time steps and rewards); those
remain available through ``BRAX_TASKS`` (``envs/brax_mujoco.py``) with the same contract.

Deviation from the paper (docs/algorithm.md, "Deviations from the paper"): the paper ran
gym's v1 tasks on MuJoCo 1.31, which cannot run here. v5 differs in details:
IDP's observation has 9 entries (v1: 11), no alive bonus on the terminal step,
Reacher's reward uses the post-step distance.

Contract (shared by ``GYMNASIUM_TASKS`` and ``envs/brax_mujoco.py``'s ``BRAX_TASKS``):

* the math is written for ONE env (no batch dim); callers ``jax.vmap``;
* ``step`` takes actions in the normalised box [-1, 1]^action_size (clipped,
  then mapped linearly onto the actuators' ``ctrlrange``);
* ``State.done`` is gymnasium's ``terminated`` (float32 1.0/0.0), with NO time
  limit: truncation is added by a wrapper elsewhere;
* ``State.info`` is left to the wrappers (empty at reset); ``State.metrics``
  holds gymnasium's per-step reward components (float32 scalars, the same
  keys at reset, zero there);
* float32 throughout (x64 stays disabled).

MJX support (mujoco-mjx 3.17 with mujoco 4.0): every option these models use
is supported as is, so NO model option is changed: RK4 (IP, IDP, Reacher,
Hopper) and Euler (HalfCheetah) integrators, the default pyramidal cone and
Newton solver, and the primitive contact pairs of Hopper and HalfCheetah
(capsule/plane, capsule/capsule, with Hopper's geom margin). The remaining
differences from gymnasium are float32 arithmetic and MJX's own collision
and solver code (see tests/test_envs_mujoco.py for the measured deviations).

Speed: MJX's line search exits early (``early_exit_linesearch``, default on; the
physics is unchanged): see ``envs/mujoco_base.py``. The base class ``GymMujocoEnv``,
model loading and ``state_from_qpos_qvel`` are there too.
"""

from __future__ import annotations

from typing import Callable, Dict, Tuple

import jax
import jax.numpy as jnp
import mujoco
from brax.envs.base import Env

import envs
from envs.mujoco_base import GymMujocoEnv, _norm, _square

__all__ = [
    "InvertedPendulum",
    "InvertedDoublePendulum",
    "Hopper",
    "HalfCheetah",
    "Reacher",
    "GYMNASIUM_TASKS",
]


class InvertedPendulum(GymMujocoEnv):
    """gymnasium ``InvertedPendulum-v5`` (inverted_pendulum_v5.py) on MJX.

    obs = [qpos, qvel] (4); reward 1 while alive; terminated when the pole
    angle |qpos[1]| > 0.2 or the observation is non-finite; reset noise
    uniform(+-reset_noise_scale) on qpos and qvel. ctrlrange is [-3, 3].
    """

    gym_id = "InvertedPendulum-v5"
    _metric_keys = ("reward_survive",)

    def __init__(
        self,
        xml_file: str = "inverted_pendulum.xml",
        frame_skip: int = 2,
        reset_noise_scale: float = 0.01,
        early_exit_linesearch: bool = True,
    ):
        super().__init__(xml_file, frame_skip, early_exit_linesearch)
        self._reset_noise_scale = reset_noise_scale

    def _obs_size(self):
        return self.mj_model.nq + self.mj_model.nv

    def _get_obs(self, xp, data):
        return xp.concatenate([data.qpos, data.qvel], axis=-1)

    def sample_qpos_qvel(self, rng):
        k1, k2 = jax.random.split(rng)
        s = self._reset_noise_scale
        return (
            self.init_qpos + self._uniform(k1, self.mj_model.nq, s),
            self.init_qvel + self._uniform(k2, self.mj_model.nv, s),
        )

    def _reward_done(self, xp, data0, data, ctrl, obs):
        terminated = xp.logical_or(~xp.all(xp.isfinite(obs), axis=-1), xp.abs(obs[..., 1]) > 0.2)
        reward = 1.0 - terminated.astype(obs.dtype)
        return reward, terminated, {"reward_survive": reward}


class InvertedDoublePendulum(GymMujocoEnv):
    """gymnasium ``InvertedDoublePendulum-v5`` (inverted_double_pendulum_v5.py).

    obs = [cart x, sin(angles), cos(angles), clip(qvel, +-10),
    clip(qfrc_constraint[0], +-10)] (9); terminated when the tip site's height
    y <= 1; reward = healthy_reward * alive - distance - velocity penalties;
    reset noise uniform(+-s) on qpos, normal(0, s) on qvel.
    """

    gym_id = "InvertedDoublePendulum-v5"
    _metric_keys = ("reward_survive", "distance_penalty", "velocity_penalty")
    derived_fields = ("site_xpos", "qfrc_constraint")

    def __init__(
        self,
        xml_file: str = "inverted_double_pendulum.xml",
        frame_skip: int = 5,
        healthy_reward: float = 10.0,
        reset_noise_scale: float = 0.1,
        early_exit_linesearch: bool = True,
    ):
        super().__init__(xml_file, frame_skip, early_exit_linesearch)
        self._healthy_reward = healthy_reward
        self._reset_noise_scale = reset_noise_scale

    def _obs_size(self):
        nq, nv = self.mj_model.nq, self.mj_model.nv
        return 1 + 2 * (nq - 1) + nv + 1

    def _get_obs(self, xp, data):
        return xp.concatenate(
            [
                data.qpos[..., :1],
                xp.sin(data.qpos[..., 1:]),
                xp.cos(data.qpos[..., 1:]),
                xp.clip(data.qvel, -10.0, 10.0),
                xp.clip(data.qfrc_constraint, -10.0, 10.0)[..., :1],
            ],
            axis=-1,
        )

    def sample_qpos_qvel(self, rng):
        k1, k2 = jax.random.split(rng)
        s = self._reset_noise_scale
        qpos = self.init_qpos + self._uniform(k1, self.mj_model.nq, s)
        qvel = self.init_qvel + s * jax.random.normal(k2, (self.mj_model.nv,), jnp.float32)
        return qpos, qvel

    def _reward_done(self, xp, data0, data, ctrl, obs):
        # gymnasium reads site_xpos[0] after mj_step, i.e. as left by the last
        # forward pass inside the step; mjx.Data and the C engine's outputs hold
        # the same quantity.
        x, y = data.site_xpos[..., 0, 0], data.site_xpos[..., 0, 2]
        terminated = y <= 1.0
        v1, v2 = data.qvel[..., 1], data.qvel[..., 2]
        dist_penalty = 0.01 * _square(xp, x) + _square(xp, y - 2.0)
        vel_penalty = 1e-3 * _square(xp, v1) + 5e-3 * _square(xp, v2)
        alive_bonus = self._healthy_reward * (1.0 - terminated.astype(obs.dtype))
        reward = alive_bonus - dist_penalty - vel_penalty
        metrics = {
            "reward_survive": alive_bonus,
            "distance_penalty": -dist_penalty,
            "velocity_penalty": -vel_penalty,
        }
        return reward, terminated, metrics


class _LocomotionMixin:
    """Forward-velocity and control-cost terms shared by Hopper/HalfCheetah."""

    def _obs_size(self):
        return self.mj_model.nq + self.mj_model.nv - int(self._exclude_current_positions_from_observation)

    def _positions_obs(self, data):
        qpos = data.qpos[..., 1:] if self._exclude_current_positions_from_observation else data.qpos
        return qpos

    def _forward_and_ctrl(self, xp, data0, data, ctrl):
        x_velocity = (data.qpos[..., 0] - data0.qpos[..., 0]) / self.dt
        forward_reward = self._forward_reward_weight * x_velocity
        # gymnasium charges the action it was given; with ctrlrange [-1, 1]
        # that equals ctrl (ours is clipped to the range first).
        ctrl_cost = self._ctrl_cost_weight * xp.sum(xp.square(ctrl), axis=-1)
        return forward_reward, ctrl_cost


class Hopper(_LocomotionMixin, GymMujocoEnv):
    """gymnasium ``Hopper-v5`` (hopper_v5.py) on MJX.

    obs = [qpos[1:], clip(qvel, +-10)] (11); reward = forward velocity +
    healthy_reward * healthy - ctrl cost; terminated when unhealthy (z, torso
    angle or |state[2:]| out of the healthy ranges); reset noise
    uniform(+-reset_noise_scale) on qpos and qvel.
    """

    gym_id = "Hopper-v5"
    _metric_keys = ("reward_forward", "reward_ctrl", "reward_survive")

    def __init__(
        self,
        xml_file: str = "hopper.xml",
        frame_skip: int = 4,
        forward_reward_weight: float = 1.0,
        ctrl_cost_weight: float = 1e-3,
        healthy_reward: float = 1.0,
        terminate_when_unhealthy: bool = True,
        healthy_state_range: Tuple[float, float] = (-100.0, 100.0),
        healthy_z_range: Tuple[float, float] = (0.7, float("inf")),
        healthy_angle_range: Tuple[float, float] = (-0.2, 0.2),
        reset_noise_scale: float = 5e-3,
        exclude_current_positions_from_observation: bool = True,
        early_exit_linesearch: bool = True,
    ):
        super().__init__(xml_file, frame_skip, early_exit_linesearch)
        self._forward_reward_weight = forward_reward_weight
        self._ctrl_cost_weight = ctrl_cost_weight
        self._healthy_reward = healthy_reward
        self._terminate_when_unhealthy = terminate_when_unhealthy
        self._healthy_state_range = healthy_state_range
        self._healthy_z_range = healthy_z_range
        self._healthy_angle_range = healthy_angle_range
        self._reset_noise_scale = reset_noise_scale
        self._exclude_current_positions_from_observation = (
            exclude_current_positions_from_observation
        )

    def _get_obs(self, xp, data):
        return xp.concatenate([self._positions_obs(data), xp.clip(data.qvel, -10.0, 10.0)], axis=-1)

    def sample_qpos_qvel(self, rng):
        k1, k2 = jax.random.split(rng)
        s = self._reset_noise_scale
        return (
            self.init_qpos + self._uniform(k1, self.mj_model.nq, s),
            self.init_qvel + self._uniform(k2, self.mj_model.nv, s),
        )

    def is_healthy(self, data, xp=jnp) -> jax.Array:
        """gymnasium's ``HopperEnv.is_healthy`` (strict inequalities)."""
        z, angle = data.qpos[..., 1], data.qpos[..., 2]
        state = xp.concatenate([data.qpos, data.qvel], axis=-1)[..., 2:]
        min_state, max_state = self._healthy_state_range
        min_z, max_z = self._healthy_z_range
        min_angle, max_angle = self._healthy_angle_range
        healthy_state = xp.all((min_state < state) & (state < max_state), axis=-1)
        healthy_z = (min_z < z) & (z < max_z)
        healthy_angle = (min_angle < angle) & (angle < max_angle)
        return healthy_state & healthy_z & healthy_angle

    def _reward_done(self, xp, data0, data, ctrl, obs):
        healthy = self.is_healthy(data, xp)
        forward_reward, ctrl_cost = self._forward_and_ctrl(xp, data0, data, ctrl)
        # As in gymnasium the survival bonus depends on health even when
        # terminate_when_unhealthy is False.
        healthy_reward = self._healthy_reward * healthy.astype(obs.dtype)
        reward = forward_reward + healthy_reward - ctrl_cost
        terminated = ~healthy if self._terminate_when_unhealthy else xp.zeros(healthy.shape, bool)
        metrics = {
            "reward_forward": forward_reward,
            "reward_ctrl": -ctrl_cost,
            "reward_survive": healthy_reward,
        }
        return reward, terminated, metrics


class HalfCheetah(_LocomotionMixin, GymMujocoEnv):
    """gymnasium ``HalfCheetah-v5`` (half_cheetah_v5.py) on MJX.

    obs = [qpos[1:], qvel] (17, qvel NOT clipped); reward = forward velocity
    - ctrl cost; never terminates; reset noise uniform(+-s) on qpos, normal(0,
    s) on qvel.
    """

    gym_id = "HalfCheetah-v5"
    _metric_keys = ("reward_forward", "reward_ctrl")

    def __init__(
        self,
        xml_file: str = "half_cheetah.xml",
        frame_skip: int = 5,
        forward_reward_weight: float = 1.0,
        ctrl_cost_weight: float = 0.1,
        reset_noise_scale: float = 0.1,
        exclude_current_positions_from_observation: bool = True,
        early_exit_linesearch: bool = True,
    ):
        super().__init__(xml_file, frame_skip, early_exit_linesearch)
        self._forward_reward_weight = forward_reward_weight
        self._ctrl_cost_weight = ctrl_cost_weight
        self._reset_noise_scale = reset_noise_scale
        self._exclude_current_positions_from_observation = (
            exclude_current_positions_from_observation
        )

    def _get_obs(self, xp, data):
        return xp.concatenate([self._positions_obs(data), data.qvel], axis=-1)

    def sample_qpos_qvel(self, rng):
        k1, k2 = jax.random.split(rng)
        s = self._reset_noise_scale
        qpos = self.init_qpos + self._uniform(k1, self.mj_model.nq, s)
        qvel = self.init_qvel + s * jax.random.normal(k2, (self.mj_model.nv,), jnp.float32)
        return qpos, qvel

    def _reward_done(self, xp, data0, data, ctrl, obs):
        forward_reward, ctrl_cost = self._forward_and_ctrl(xp, data0, data, ctrl)
        reward = forward_reward - ctrl_cost
        metrics = {"reward_forward": forward_reward, "reward_ctrl": -ctrl_cost}
        return reward, xp.zeros(reward.shape, bool), metrics


class Reacher(GymMujocoEnv):
    """gymnasium ``Reacher-v5`` (reacher_v5.py) on MJX.

    obs = [cos(arm angles), sin(arm angles), target xy, arm joint velocities,
    (fingertip - target)[:2]] (10); reward = -|fingertip - target| (3-D) *
    reward_dist_weight - |action|^2 * reward_control_weight; never
    terminates (gymnasium's 50-step limit is a TimeLimit, added elsewhere).
    Reset: arm angles uniform(+-0.1), target uniform on the open disc of
    radius 0.2, arm velocities uniform(+-0.005), target velocities 0.
    """

    gym_id = "Reacher-v5"
    _metric_keys = ("reward_dist", "reward_ctrl")
    derived_fields = ("xpos",)

    def __init__(
        self,
        xml_file: str = "reacher.xml",
        frame_skip: int = 2,
        reward_dist_weight: float = 1.0,
        reward_control_weight: float = 1.0,
        early_exit_linesearch: bool = True,
    ):
        super().__init__(xml_file, frame_skip, early_exit_linesearch)
        self._reward_dist_weight = reward_dist_weight
        self._reward_control_weight = reward_control_weight
        self._fingertip = mujoco.mj_name2id(self.mj_model, mujoco.mjtObj.mjOBJ_BODY, "fingertip")
        self._target = mujoco.mj_name2id(self.mj_model, mujoco.mjtObj.mjOBJ_BODY, "target")

    def _obs_size(self):
        return 10

    def _tip_to_target(self, data):
        # gymnasium's get_body_com reads body xpos (frame origin, not COM).
        return data.xpos[..., self._fingertip, :] - data.xpos[..., self._target, :]

    def _get_obs(self, xp, data):
        theta = data.qpos[..., :2]
        return xp.concatenate(
            [
                xp.cos(theta),
                xp.sin(theta),
                data.qpos[..., 2:],
                data.qvel[..., :2],
                self._tip_to_target(data)[..., :2],
            ],
            axis=-1,
        )

    def sample_qpos_qvel(self, rng):
        k_qpos, k_r, k_phi, k_qvel = jax.random.split(rng, 4)
        nq, nv = self.mj_model.nq, self.mj_model.nv
        qpos = self.init_qpos + self._uniform(k_qpos, nq, 0.1)
        # gymnasium rejection-samples the goal uniformly in [-0.2, 0.2]^2 until
        # |goal| < 0.2, i.e. uniformly on the disc; polar sampling gives the
        # same distribution without a data-dependent loop under vmap.
        r = 0.2 * jnp.sqrt(jax.random.uniform(k_r, (), jnp.float32))
        phi = jax.random.uniform(k_phi, (), jnp.float32, 0.0, 2.0 * jnp.pi)
        goal = r * jnp.array([jnp.cos(phi), jnp.sin(phi)])
        qpos = qpos.at[-2:].set(goal)
        qvel = self.init_qvel + self._uniform(k_qvel, nv, 0.005)
        qvel = qvel.at[-2:].set(0.0)
        return qpos, qvel

    def _reward_done(self, xp, data0, data, ctrl, obs):
        reward_dist = -_norm(xp, self._tip_to_target(data)) * self._reward_dist_weight
        # ctrlrange is [-1, 1], so ctrl is the action gymnasium would charge.
        reward_ctrl = -xp.sum(xp.square(ctrl), axis=-1) * self._reward_control_weight
        metrics = {"reward_dist": reward_dist, "reward_ctrl": reward_ctrl}
        return reward_dist + reward_ctrl, xp.zeros(reward_dist.shape, bool), metrics


# The built-in MuJoCo tasks' envs of source 'gymnasium', by task name: a view of their specs (envs.TASKS,
# ``entry_point``) for code that builds them directly.
GYMNASIUM_TASKS: Dict[str, Callable[..., Env]] = {
    name: envs.constructor(name) for name, spec in envs.TASKS.items() if spec.mujoco
}
