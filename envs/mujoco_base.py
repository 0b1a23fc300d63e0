"""The MuJoCo machinery every task shares: model loading (without MuJoCo's settotalmass warning),
MJX's line search with early exit, and ``GymMujocoEnv``, the base class of gymnasium's tasks.

The tasks themselves are in ``envs/gym_mujoco.py`` (gymnasium's) and ``envs/brax_mujoco.py`` (brax's).

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
unchanged. Hopper's and IDP's trajectories were bitwise equal to the stock
scan's where first measured; the two loops compile to different programs,
though, and on another CPU (CI's) Hopper's differed by up to 1.9e-6 from step
11 on, round-off. tests/test_envs_mujoco.py checks the loop against MJX's
own under ``vmap`` (bit for bit, rows stopping at once, early and at the
cap) and that our step's line search goes through it; ``python -m
experiments.bench --env-speed --stock-mjx`` compares whole trajectories
with stock MJX on every task, and the gymnasium cross-checks run with the
early exit on. Only MJX's
reverse-mode differentiability through the line search is lost, which
nothing here uses. ``early_exit_linesearch=False`` gives stock MJX.
"""

from __future__ import annotations

import contextlib
import functools
import os
import re
import warnings
from typing import Tuple

import gymnasium
import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from brax.envs.base import Env, State
from mujoco import mjx
from mujoco.mjx._src import solver as _mjx_solver

__all__ = [
    "GymMujocoEnv",
    "gymnasium_asset_path",
    "load_model",
    "state_from_qpos_qvel",
    "without_the_settotalmass_warning",
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
    # The C engine's stages at the new state after a step (mujoco.batch.Batch.step's ``stage``): none, as
    # gymnasium's mj_step leaves MjData (derived fields of the state before the last substep).
    step_stage: int = int(mujoco.mjtStage.mjSTAGE_NONE)
    # Per-env model entries a reset draws ((MjModel field, flat index) pairs; e.g. a target's position),
    # carried with the physics state; and the candidates a reset draws, of which the C engine keeps the first
    # without contacts (1: the one drawn). Both for the DeepMind Control tasks (envs/dmc.py).
    model_params: Tuple[Tuple[str, int], ...] = ()
    reset_tries: int = 1
    # Physics steps with zero controls that a reset runs from its draw (DeepMind Control's cheetah: 200;
    # ``envs.dmc.DmcTask.settle``); 0: none.
    settle_steps: int = 0

    def __init__(self, xml_file, frame_skip: int, early_exit_linesearch: bool = True):
        # See the module docstring ("Speed"); False gives MJX's stock line search.
        self.early_exit_linesearch = bool(early_exit_linesearch)
        # A gymnasium file name, or a compiled model (envs/dmc.py loads dm_control's).
        self.mj_model = (xml_file if isinstance(xml_file, mujoco.MjModel)
                         else load_model(gymnasium_asset_path(xml_file)))
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

    @functools.cached_property
    def mjx_model(self) -> mjx.Model:
        """The model on MJX (built on first use, as concrete arrays even inside a trace: the C engine does not
        need it)."""
        with jax.ensure_compile_time_eval():
            return mjx.put_model(self.mj_model)

    @functools.cached_property
    def _data0(self) -> mjx.Data:
        """A template mjx.Data (as after gymnasium's mj_resetData) that reset fills in, built once so that
        reset does no host-side work."""
        with jax.ensure_compile_time_eval():
            return mjx.make_data(self.mjx_model)

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
        """The observation of ``data`` (written once for both engines, see the class docstring)."""
        raise NotImplementedError

    def sample_qpos_qvel(self, rng: jax.Array) -> Tuple[jax.Array, jax.Array]:
        """Initial (qpos, qvel) with gymnasium's ``reset_model`` noise."""
        raise NotImplementedError

    def sample_reset(self, rng: jax.Array) -> jax.Array:
        """The reset's candidates, (reset_tries, nq + nv + len(model_params)) float32: qpos, qvel, model params."""
        qpos, qvel = self.sample_qpos_qvel(rng)
        return jnp.concatenate([qpos, qvel])[None]

    def _reward_done(self, xp, data0, data, ctrl, obs):
        """Return (reward, terminated, metrics) for the transition data0 -> data."""
        raise NotImplementedError


def state_from_qpos_qvel(env: GymMujocoEnv, qpos, qvel) -> State:
    """State of ``env`` at joint positions ``qpos`` and velocities ``qvel``.

    Mirrors gymnasium's ``MujocoEnv.set_state`` after ``mj_resetData`` (so
    derived quantities come from ``mj_forward``); used to start from a state
    copied out of gymnasium. Works under jit/vmap.
    """
    return env.state_from_qpos_qvel(qpos, qvel)
