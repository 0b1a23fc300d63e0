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
remain available through ``BRAX_TASKS`` with the same contract.

Deviation from the paper (docs/algorithm.md, "Deviations from the paper"): the paper ran
gym's v1 tasks on MuJoCo 1.31, which cannot run here. v5 differs in details:
IDP's observation has 9 entries (v1: 11), no alive bonus on the terminal step,
Reacher's reward uses the post-step distance.

Contract (shared by ``GYMNASIUM_TASKS`` and ``BRAX_TASKS``):

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

Speed: early exit of the Newton solver's line search (``early_exit_linesearch``,
default on). MJX 3.17 runs the line search as a ``lax.scan`` over
``opt.ls_iterations`` (50) steps, each a ``lax.cond`` that turns into a no-op
once the search has converged. Under ``vmap`` a ``cond`` with a batched
predicate becomes a ``select``, so all 50 steps are computed for every env on
every solver iteration, whatever the search needed. Measured on random-action
rollouts (8 envs, uniform / N(0, 0.3) / bang-bang actions): the search stops
after 0-1 steps on IDP, and after 0-9 steps on Hopper and HalfCheetah except
for searches that bisect down to float32 resolution (24-25 steps, 13-18% of
them). While
tracing our ``step`` and ``reset`` we therefore swap MJX's private
``solver._while_loop_scan`` for a ``lax.while_loop`` with the same condition
and the same cap (``_while_loop_capped``); under ``vmap`` a while loop runs
until the slowest env of the batch has converged and keeps each env's own
result. Same model, same options, same per-env iterations: the physics is
unchanged: tests/test_envs_mujoco.py asserts bitwise equality with the stock
scan on IDP and Hopper, ``python -m experiments.bench --env-speed`` checks it
on every task, and the gymnasium cross-checks run with it on. Only MJX's
reverse-mode differentiability through the line search is lost, which
nothing here uses. ``early_exit_linesearch=False`` gives stock MJX.
"""

from __future__ import annotations

import contextlib
import os
import re
import warnings
from typing import Callable, Dict, Tuple

import gymnasium
import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from brax import envs as brax_envs
from brax.envs.base import Env, State, Wrapper
from mujoco import mjx
from mujoco.mjx._src import solver as _mjx_solver

__all__ = [
    "GymMujocoEnv",
    "InvertedPendulum",
    "InvertedDoublePendulum",
    "Hopper",
    "HalfCheetah",
    "Reacher",
    "BraxTaskAdapter",
    "GYMNASIUM_TASKS",
    "BRAX_TASKS",
    "gymnasium_asset_path",
    "state_from_qpos_qvel",
]

# gymnasium's MujocoEnv resolves relative xml_file names against this folder.
_GYM_ASSETS = os.path.join(os.path.dirname(gymnasium.__file__), "envs", "mujoco", "assets")


def _while_loop_capped(cond_fun, body_fun, init_val, max_iter):
    """``lax.while_loop`` with the contract of MJX's ``solver._while_loop_scan``:
    apply ``body_fun`` while ``cond_fun`` holds, at most ``max_iter`` times."""

    def cond(carry):
        val, i = carry
        return jnp.logical_and(cond_fun(val), i < max_iter)

    def body(carry):
        val, i = carry
        return body_fun(val), i + 1

    return jax.lax.while_loop(cond, body, (init_val, jnp.zeros((), jnp.int32)))[0]


@contextlib.contextmanager
def _linesearch_loop(early_exit: bool):
    """While active (i.e. while a step is traced), MJX's line search exits early."""
    if not early_exit or not hasattr(_mjx_solver, "_while_loop_scan"):
        if early_exit:
            warnings.warn("mujoco.mjx._src.solver._while_loop_scan not found (another mujoco-mjx "
                          "version?): early_exit_linesearch ignored, MJX's stock line search is used")
        yield
        return
    stock = _mjx_solver._while_loop_scan
    _mjx_solver._while_loop_scan = _while_loop_capped
    try:
        yield
    finally:
        _mjx_solver._while_loop_scan = stock


_SETTOTALMASS = re.compile(r'\s+settotalmass="([^"]+)"')


def load_model(path: str) -> mujoco.MjModel:
    """Compiles a gymnasium XML file, the way MuJoCo's deprecation warning for the compiler attribute
    ``settotalmass`` asks (HalfCheetah's model has ``settotalmass="14"``): the attribute is taken out and
    ``mj_setTotalmass`` and ``mj_setConst`` are applied to the compiled model. Every array of the model
    equals the one compiled from the file as it is, bit for bit (checked on HalfCheetah with MuJoCo
    4.0.1; tests/test_envs_mujoco.py compares them), and MuJoCo writes no warning, so no
    ``MUJOCO_LOG.TXT`` lands in the working directory. Other files are compiled as they are."""
    with open(path) as f:
        xml = f.read()
    found = _SETTOTALMASS.search(xml)
    if found is None:
        return mujoco.MjModel.from_xml_path(path)
    # Compiled from a string: gymnasium's five task models name no other files (meshes, includes).
    model = mujoco.MjModel.from_xml_string(_SETTOTALMASS.sub("", xml, count=1))
    mujoco.mj_setTotalmass(model, float(found.group(1)))
    mujoco.mj_setConst(model, mujoco.MjData(model))
    return model


def gymnasium_asset_path(xml_file: str) -> str:
    """Path of an XML file as gymnasium's ``expand_model_path`` resolves it."""
    if xml_file.startswith((".", "/")):
        return xml_file
    if xml_file.startswith("~"):
        return os.path.expanduser(xml_file)
    return os.path.join(_GYM_ASSETS, xml_file)


def _square(xp, x):
    """``x**2`` as gymnasium computes it on numpy float64 *scalars*: C ``pow(x, 2)``, which differs
    from ``x * x`` in the last bit for ~0.1% of values (numpy arrays' ``**2`` is ``x * x``;
    ``np.float_power`` calls ``pow``). With ``jnp`` (MJX, float32) simply ``x**2``."""
    if xp is np:
        return np.float_power(x, 2.0)
    return x**2


def _norm(xp, v):
    """Euclidean norm over the last axis, as gymnasium's ``np.linalg.norm`` of one vector computes it."""
    if xp is np:
        # numpy's 1-D norm is sqrt(v.dot(v)); rows one at a time so a batch gives the same bits.
        flat = v.reshape(-1, v.shape[-1])
        return np.array([np.linalg.norm(r) for r in flat]).reshape(v.shape[:-1])
    return xp.linalg.norm(v, axis=-1)


class GymMujocoEnv(Env):
    """Shared machinery of the gymnasium-on-MJX tasks (gymnasium ``MujocoEnv``).

    Subclasses set ``gym_id`` and implement ``_obs_size``, ``_get_obs``,
    ``sample_qpos_qvel`` (reset noise) and ``_reward_done``; ``_metric_keys``
    lists the reward components written to ``State.metrics``.

    The task math (``_get_obs``, ``_reward_done``, ``is_healthy``) is written
    once for both engines: it takes the array module ``xp`` and a physics view
    ``data`` with ``qpos``, ``qvel`` and the ``derived_fields`` the task reads
    (MJX: ``jax.numpy`` on one ``mjx.Data``, float32; MuJoCo's C engine,
    ``envs/mujoco_c.py``: ``numpy`` on (n, ...) float64 arrays of a batch), so
    it indexes with ``[..., i]`` and reduces over ``axis=-1``.
    """

    gym_id: str = ""
    _metric_keys: Tuple[str, ...] = ()
    # MjData fields besides qpos/qvel that _get_obs/_reward_done read (computed by the step).
    derived_fields: Tuple[str, ...] = ()

    def __init__(self, xml_file: str, frame_skip: int, early_exit_linesearch: bool = True):
        # See the module docstring ("Speed"); False gives MJX's stock line search.
        self.early_exit_linesearch = bool(early_exit_linesearch)
        self.mj_model = load_model(gymnasium_asset_path(xml_file))
        self.mjx_model = mjx.put_model(self.mj_model)
        # A template mjx.Data (as after gymnasium's mj_resetData) that reset
        # fills in; built once here so reset does no host-side work.
        self._data0 = mjx.make_data(self.mjx_model)
        self.frame_skip = int(frame_skip)
        # Python float, as gymnasium's MujocoEnv.dt (timestep * frame_skip).
        self.dt = float(self.mj_model.opt.timestep) * self.frame_skip
        # gymnasium's init_qpos/init_qvel are MjData's values after creation.
        self.init_qpos = jnp.asarray(self.mj_model.qpos0, dtype=jnp.float32)
        self.init_qvel = jnp.zeros(self.mj_model.nv, dtype=jnp.float32)
        # Action space of gymnasium's MujocoEnv is the actuators' ctrlrange; we
        # expose [-1, 1] instead and rescale in step.
        ctrlrange = np.asarray(self.mj_model.actuator_ctrlrange, dtype=np.float32)
        self._ctrl_low = jnp.asarray(ctrlrange[:, 0])
        self._ctrl_high = jnp.asarray(ctrlrange[:, 1])
        # float64 for the C engine, which scales on the host (envs/mujoco_c.py).
        self._ctrlrange64 = np.array(self.mj_model.actuator_ctrlrange, dtype=np.float64)

    # -- Brax Env interface -------------------------------------------------

    @property
    def observation_size(self) -> int:
        return self._obs_size()

    @property
    def action_size(self) -> int:
        return int(self.mj_model.nu)

    @property
    def backend(self) -> str:
        return "mjx"

    def reset(self, rng: jax.Array) -> State:
        qpos, qvel = self.sample_qpos_qvel(rng)
        return self.state_from_qpos_qvel(qpos, qvel)

    def step(self, state: State, action: jax.Array) -> State:
        action = jnp.clip(jnp.asarray(action, jnp.float32), -1.0, 1.0)
        ctrl = self.scale_action(action)
        data0 = state.pipeline_state
        data = data0.replace(ctrl=ctrl)
        # gymnasium's do_simulation: ctrl held for frame_skip mj_steps. (Its
        # extra mj_rnePostConstraint only fills cacc/cfrc_*, unused here.)
        with _linesearch_loop(self.early_exit_linesearch):
            data = jax.lax.fori_loop(
                0, self.frame_skip, lambda _, d: mjx.step(self.mjx_model, d), data
            )
        obs = self._get_obs(jnp, data)
        reward, terminated, metrics = self._reward_done(jnp, data0, data, ctrl, obs)
        return state.replace(
            pipeline_state=data,
            obs=obs,
            reward=jnp.asarray(reward, jnp.float32),
            done=jnp.asarray(terminated, jnp.float32),
            metrics={k: jnp.asarray(v, jnp.float32) for k, v in metrics.items()},
        )

    # -- helpers --------------------------------------------------------------

    def scale_action(self, action: jax.Array, xp=jnp) -> jax.Array:
        """Map a normalised action in [-1, 1] linearly onto ctrlrange (float32 with ``jnp``,
        float64 with ``np``)."""
        if xp is np:
            low, high = self._ctrlrange64[:, 0], self._ctrlrange64[:, 1]
            return low + (np.asarray(action, np.float64) + 1.0) * 0.5 * (high - low)
        return self._ctrl_low + (action + 1.0) * 0.5 * (self._ctrl_high - self._ctrl_low)

    def state_from_qpos_qvel(self, qpos: jax.Array, qvel: jax.Array) -> State:
        """State with the given joint positions/velocities, as gymnasium's
        ``reset`` (``mj_resetData`` then ``set_state``, i.e. ``mj_forward``)."""
        data = self._data0.replace(
            qpos=jnp.asarray(qpos, jnp.float32), qvel=jnp.asarray(qvel, jnp.float32)
        )
        # forward fills the derived quantities (site/body positions, constraint
        # forces) that gymnasium's reset observations read.
        with _linesearch_loop(self.early_exit_linesearch):
            data = mjx.forward(self.mjx_model, data)
        zero = jnp.zeros((), jnp.float32)
        return State(
            pipeline_state=data,
            obs=self._get_obs(jnp, data),
            reward=zero,
            done=zero,
            metrics={k: zero for k in self._metric_keys},
            info={},
        )

    def _uniform(self, rng, size, scale):
        return jax.random.uniform(rng, (size,), jnp.float32, -scale, scale)

    # -- per task ---------------------------------------------------------------

    def _obs_size(self) -> int:
        raise NotImplementedError

    def _get_obs(self, xp, data) -> jax.Array:
        """The observation of ``data`` (written once for both engines, see the module docstring)."""
        raise NotImplementedError

    def sample_qpos_qvel(self, rng: jax.Array) -> Tuple[jax.Array, jax.Array]:
        """Initial (qpos, qvel) with gymnasium's ``reset_model`` noise."""
        raise NotImplementedError

    def _reward_done(self, xp, data0, data, ctrl, obs):
        """Return (reward, terminated, metrics) for the transition data0 -> data."""
        raise NotImplementedError


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


def state_from_qpos_qvel(env: GymMujocoEnv, qpos, qvel) -> State:
    """State of ``env`` at joint positions ``qpos`` and velocities ``qvel``.

    Mirrors gymnasium's ``MujocoEnv.set_state`` after ``mj_resetData`` (so
    derived quantities come from ``mj_forward``); used to start from a state
    copied out of gymnasium. Works under jit/vmap.
    """
    return env.state_from_qpos_qvel(qpos, qvel)


GYMNASIUM_TASKS: Dict[str, Callable[..., Env]] = {
    "inverted_pendulum": InvertedPendulum,
    "inverted_double_pendulum": InvertedDoublePendulum,
    "hopper": Hopper,
    "halfcheetah": HalfCheetah,
    "reacher": Reacher,
}


# --- brax's own versions, adapted to the same contract ------------------------


class BraxTaskAdapter(Wrapper):
    """Brax's own task env (mjx backend) under this module's contract.

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


@contextlib.contextmanager
def without_the_settotalmass_warning():
    """While brax (or gymnasium, the tests' reference) compiles a model file it reads itself, where
    ``load_model``'s fix cannot reach: MuJoCo's deprecation warning for ``settotalmass`` (brax's and
    gymnasium's half_cheetah.xml) is dropped instead of going to MUJOCO_LOG.TXT in the working directory; any other MuJoCo warning is
    a Python warning. Installed on the calling thread around model loading only, then restored."""
    def handler(message: str) -> None:
        if "'settotalmass' is deprecated" not in message:
            warnings.warn(f"MuJoCo: {message}", RuntimeWarning, stacklevel=2)

    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(handler)
    try:
        yield
    finally:
        mujoco.set_mju_user_warning(previous)


def _brax_task(name: str) -> Callable[..., Env]:
    def make(**overrides) -> Env:
        with without_the_settotalmass_warning():
            env = brax_envs.get_environment(name, backend="mjx", **overrides)
        return BraxTaskAdapter(env, name)

    make.__name__ = f"brax_{name}"
    make.__doc__ = f"brax's own '{name}' env on the mjx backend, adapted to the contract."
    return make


BRAX_TASKS: Dict[str, Callable[..., Env]] = {
    name: _brax_task(name)
    for name in (
        "inverted_pendulum",
        "inverted_double_pendulum",
        "hopper",
        "halfcheetah",
        "reacher",
    )
}
