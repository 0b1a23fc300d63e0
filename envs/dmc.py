"""DeepMind Control suite tasks (``dmc:<domain>-<task>``) on MuJoCo's C engine and on MJX: the shared machinery
(dm_control's models, its reward sigmoids, ``DmcTask``). The tasks are in modules per group of domains:
``envs/dmc_classic.py`` (cartpole, pendulum, ball_in_cup, reacher, point_mass, acrobot), ``envs/dmc_finger.py``
(finger) and ``envs/dmc_locomotion.py`` (hopper, walker, cheetah).

Reference: the installed ``dm_control`` package (``dm_control/suite/<domain>.py``, ``utils/rewards.py``,
``rl/control.py``, ``mujoco/engine.py``). The models are dm_control's own XML files and their shared assets
(``suite/common/*.xml``), read from the installed package at run time; the task math (observation, reward,
reset distribution) is written here once, array-generically (``xp`` is numpy on the C engine's float64 batch,
``jax.numpy`` on one ``mjx.Data`` in float32), as ``envs/gym_mujoco.py`` does for gymnasium's tasks:

* **observation**: dm_control's ``OrderedDict`` flattened in its key order, each entry flattened;
* **reward**: dm_control's, with its ``rewards.tolerance`` sigmoids (``tolerance`` below), in [0, 1] per step;
* **termination**: none (these tasks end at their time limit only: ``done`` is always 0; the 1,000-step limit
  is the registry's wrapper, ``envs.dmc_names.EPISODE_LENGTH``);
* **control step**: dm_control's control timestep, i.e. ``frame_skip`` physics steps with the action held;
  actions in [-1, 1] are the actuators' controls (every actuator here is ctrllimited to [-1, 1]);
* **derived fields after a step**: dm_control's ``Physics.step`` ends with ``mj_step1``, so positions, rotation
  matrices and position/velocity sensors belong to the *new* state (a plain ``mj_step`` leaves them one substep
  behind). The C engine asks ``mujoco.batch.Batch.step`` for ``mjSTAGE_VEL`` at the new state (``step_stage``),
  MJX runs ``mjx.kinematics`` after the last substep, or, for tasks that read sensors (``reads_sensors``),
  ``mj_step1``'s position and velocity stages with their sensors (``_step1``). Acceleration-stage sensors
  (touch) are not recomputed by ``mj_step1``: they keep the values of the last substep's ``mj_step2``, i.e. of
  the state before the last substep, on both engines as in dm_control;
* **reset**: dm_control's ``initialize_episode`` distribution drawn with JAX's PRNG in float32 (the same
  distribution, not the same draws). Model entries a reset draws (Reacher's and finger-turn's targets) are
  per-env model parameters (``model_params``) carried with the physics state. Ball-in-cup's and finger's "redraw
  while penetrating" loops keep the first of ``reset_tries`` draws without contacts (``HostPhysics`` /
  ``_first_free`` below).
  Cheetah's reset lets its draw settle for 200 physics steps (``settle_steps``; ``settle`` below, and
  ``_settle`` on MJX), the first of them from the derived fields of ``qpos0`` as dm_control's ``mj_step2`` does.
"""

from __future__ import annotations

import copy
import functools
import importlib.util
import os

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from brax.envs.base import State
from flax import struct
from mujoco import mjx
from mujoco.mjx._src import forward as mjx_forward
from mujoco.mjx._src import sensor as mjx_sensor
from mujoco.mjx._src import smooth as mjx_smooth

from envs.mujoco_base import _SETTOTALMASS, GymMujocoEnv, _linesearch_loop

__all__ = ["DmcTask", "MjxState", "load_model", "tolerance"]

_ASSETS = ("materials.xml", "skybox.xml", "visual.xml")


@functools.lru_cache(maxsize=None)
def _model_files(domain: str) -> tuple[str, tuple[tuple[str, bytes], ...]]:
    from envs.dmc_names import require_dm_control

    require_dm_control(f"dmc:{domain}")
    suite = os.path.join(importlib.util.find_spec("dm_control").submodule_search_locations[0], "suite")
    with open(os.path.join(suite, f"{domain}.xml")) as f:
        xml = f.read()
    assets = []
    for name in _ASSETS:
        with open(os.path.join(suite, "common", name), "rb") as f:
            assets.append((f"./common/{name}", f.read()))
    return xml, tuple(assets)


def load_model(domain: str) -> mujoco.MjModel:
    """dm_control's model of ``domain`` (``suite.<domain>.get_model_and_assets()``: the domain's XML and the
    suite's common assets, read from the installed package without importing its Python). Cheetah's
    ``settotalmass`` is applied as ``envs.mujoco_base.load_model`` does (the same arrays, without MuJoCo's
    deprecation warning)."""
    xml, assets = _model_files(domain)
    found = _SETTOTALMASS.search(xml)
    if found is None:
        return mujoco.MjModel.from_xml_string(xml, dict(assets))
    model = mujoco.MjModel.from_xml_string(_SETTOTALMASS.sub("", xml, count=1), dict(assets))
    mujoco.mj_setTotalmass(model, float(found.group(1)))
    mujoco.mj_setConst(model, mujoco.MjData(model))
    return model


def _power2(xp, x, scalar: bool):
    """``x**2`` as dm_control computes it: on a NumPy float64 scalar it is C ``pow`` (``np.float_power``), on an
    array ``x * x``; the two differ in the last bit for a few values."""
    if xp is np and scalar:
        return np.float_power(x, 2.0)
    return x * x


def tolerance(xp, x, bounds=(0.0, 0.0), margin=0.0, sigmoid="gaussian", value_at_margin=0.1, scalar=False):
    """dm_control's ``rewards.tolerance``: 1 inside ``bounds`` (inclusive), else a sigmoid of the distance to
    the nearest bound in units of ``margin`` (0 outside when ``margin`` is 0), worth ``value_at_margin`` at one
    margin. Element-wise; ``scalar`` says whether dm_control applies it to a scalar (its squares differ, see
    ``_power2``)."""
    lower, upper = bounds
    in_bounds = (lower <= x) & (x <= upper)
    if margin == 0:
        return xp.where(in_bounds, 1.0, 0.0).astype(x.dtype)
    d = xp.where(x < lower, lower - x, x - upper) / margin
    v = value_at_margin
    if sigmoid == "gaussian":
        value = xp.exp(-0.5 * _power2(xp, d * float(np.sqrt(-2 * np.log(v))), scalar))
    elif sigmoid == "long_tail":
        value = 1 / (_power2(xp, d * float(np.sqrt(1 / v - 1)), scalar) + 1)
    elif sigmoid == "reciprocal":
        value = 1 / (abs(d) * (1 / v - 1) + 1)
    elif sigmoid == "hyperbolic":
        value = 1 / xp.cosh(d * float(np.arccosh(1 / v)))
    elif sigmoid == "linear":
        scaled = d * (1 - v)
        value = xp.where(abs(scaled) < 1, 1 - scaled, 0.0)
    elif sigmoid == "quadratic":
        scaled = d * float(np.sqrt(1 - v))
        value = xp.where(abs(scaled) < 1, 1 - _power2(xp, scaled, scalar), 0.0)
    else:
        raise ValueError(f"unknown sigmoid {sigmoid!r}")
    return xp.where(in_bounds, 1.0, value).astype(x.dtype)


def _xmat(data):
    """Rotation matrices as (..., nbody, 9) rows (MJX keeps (nbody, 3, 3), the C engine's batch (n, nbody, 9));
    dm_control's ``xmat[body, 'zz']`` is entry 8, ``'xz'`` entry 2."""
    m = data.xmat
    return m.reshape(*m.shape[:-2], 9) if m.shape[-1] == 3 else m


@struct.dataclass
class MjxState:
    """The physics state on MJX: the simulation and the env's model parameters (``DmcTask.model_params``)."""

    data: mjx.Data
    params: jax.Array


class DmcTask(GymMujocoEnv):
    """The shared machinery of the DeepMind Control tasks (one env; the C engine batches it, MJX vmaps it).

    Subclasses set ``domain`` (dm_control's model), implement ``_obs_size``, ``_get_obs``, ``_reward`` and
    ``sample_reset``, and may set ``control_timestep`` (default: one physics step per control step, as
    dm_control's ``control.Environment``), ``derived_fields``, ``model_params``, ``reset_tries``,
    ``settle_steps`` and ``reads_sensors``.
    """

    domain = ""
    control_timestep: float | None = None
    step_stage = int(mujoco.mjtStage.mjSTAGE_VEL)
    # Whether the observation or reward reads ``sensordata`` (MJX then recomputes the position- and
    # velocity-stage sensors at the new state after a step, as mj_step1 does).
    reads_sensors = False

    def __init__(self, early_exit_linesearch: bool = True):
        model = self._configure(load_model(self.domain))
        dt = self.control_timestep
        frame_skip = 1 if dt is None else int(round(dt / model.opt.timestep))
        super().__init__(model, frame_skip, early_exit_linesearch)
        self.gym_id = f"dmc:{self.domain}"

    def _configure(self, model: mujoco.MjModel) -> mujoco.MjModel:
        """The task's fixed changes to the model (e.g. Reacher's target size)."""
        return model

    def _id(self, kind: str, name: str) -> int:
        return mujoco.mj_name2id(self.mj_model, getattr(mujoco.mjtObj, f"mjOBJ_{kind.upper()}"), name)

    def _uniform_in(self, rng, shape, low, high):
        return jax.random.uniform(rng, shape, jnp.float32, low, high)

    def joint_draws(self, rng) -> jax.Array:
        """dm_control's ``randomize_limited_and_rotational_joints`` on qpos0: limited hinges and slides uniform in
        their range, unlimited hinges in [-pi, pi), other joints left at qpos0 (ball and free joints are not
        drawn: no domain of this batch has one)."""
        m = self.mj_model
        qpos = self.init_qpos
        keys = jax.random.split(rng, max(m.njnt, 1))
        for j in range(m.njnt):
            kind, adr = mujoco.mjtJoint(int(m.jnt_type[j])), int(m.jnt_qposadr[j])
            if kind in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
                if m.jnt_limited[j]:
                    qpos = qpos.at[adr].set(self._uniform_in(keys[j], (), *m.jnt_range[j]))
                elif kind == mujoco.mjtJoint.mjJNT_HINGE:
                    qpos = qpos.at[adr].set(self._uniform_in(keys[j], (), -np.pi, np.pi))
            else:
                raise NotImplementedError("ball and free joints are not drawn yet")
        return qpos

    def _candidate(self, qpos, qvel=None, params=()):
        """One reset candidate row: qpos, qvel (default zero), model params."""
        qvel = self.init_qvel if qvel is None else qvel
        return jnp.concatenate([qpos, qvel, jnp.asarray(params, jnp.float32).reshape(-1)])

    def settle(self, rows: np.ndarray) -> np.ndarray:
        """The C engine's settling of reset draws (``settle_steps``): float64 integration state rows (n, nstate)
        at their draws -> the rows after dm_control's ``physics.step(settle_steps)`` with zero controls, time 0.
        As in dm_control's reset: the first substep's ``mj_step2`` runs on the derived fields of its reset's
        ``mj_forward`` at qpos0 and integrates from the draw; then ``mj_step`` x (n - 1) and ``mj_step1``."""
        m, d = self.mj_model, mujoco.MjData(self.mj_model)
        spec, out = mujoco.mjtState.mjSTATE_INTEGRATION, np.empty_like(rows)
        for i, row in enumerate(rows):
            mujoco.mj_resetData(m, d)
            mujoco.mj_forward(m, d)
            mujoco.mj_setState(m, d, row, spec)
            mujoco.mj_step2(m, d)
            mujoco.mj_step(m, d, self.settle_steps - 1)
            mujoco.mj_step1(m, d)
            d.time = 0.0
            mujoco.mj_getState(m, d, out[i], spec)
        return out

    def _reward_done(self, xp, data0, data, ctrl, obs):
        reward = self._reward(xp, data, ctrl)
        return reward, xp.zeros(reward.shape, bool), {}

    def _reward(self, xp, data, ctrl):
        raise NotImplementedError

    # -- MJX -----------------------------------------------------------------------------

    @functools.cached_property
    def mjx_model(self) -> mjx.Model:
        """The model on MJX, without the energy flag (cartpole, pendulum, acrobot set it; MJX does not support it
        and it only computes the energy, which no task reads)."""
        model = copy.copy(self.mj_model)
        model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_ENERGY)
        with jax.ensure_compile_time_eval():
            return mjx.put_model(model)

    def _model(self, params: jax.Array) -> mjx.Model:
        """The MJX model with this env's model parameters written in."""
        m = self.mjx_model
        for j, (field, index) in enumerate(self.model_params):
            value = getattr(m, field)
            m = m.replace(**{field: value.reshape(-1).at[index].set(params[j]).reshape(value.shape)})
        return m

    def _place(self, row: jax.Array, settle=True):
        nq, nv = self.mj_model.nq, self.mj_model.nv
        params, model = row[nq + nv:], self._model(row[nq + nv:])
        data = self._data0.replace(qpos=row[:nq], qvel=row[nq:nq + nv])
        if self.settle_steps:
            data = self._settle(model, data, settle)
        return mjx.forward(model, data), params

    @functools.cached_property
    def _forward0(self) -> mjx.Data:
        """``mjx.forward`` at qpos0, at rest: the derived fields dm_control's first settling substep reads."""
        with jax.ensure_compile_time_eval():
            return jax.jit(mjx.forward)(self.mjx_model, self._data0)

    def _settle(self, model, data, settle):
        """MJX's ``settle``: one Euler step from ``_forward0``'s derived fields with the drawn qpos/qvel, then
        ``settle_steps - 1`` ``mjx.step``s, time 0. Where ``settle`` is False (the auto-reset's draws that are not
        used, ``step_with_reset``) the loop runs no step: under vmap it runs as long as the longest env needs."""
        d = mjx_forward.euler(model, self._forward0.replace(qpos=data.qpos, qvel=data.qvel))
        n = jnp.where(settle, self.settle_steps - 1, 0)
        d = jax.lax.while_loop(lambda c: c[0] < n, lambda c: (c[0] + 1, mjx.step(model, c[1])), (0, d))[1]
        return d.replace(time=jnp.zeros_like(d.time))

    def _first_free(self, tries: jax.Array):
        """The first candidate whose ``mjx.forward`` finds no contact (the last if none), as ``HostPhysics``."""
        def penetrating(data):
            return jnp.any(data._impl.contact.dist < 0)  # MJX keeps every candidate contact, with its distance

        def cond(carry):
            k, data, _ = carry
            return (k < len(tries)) & penetrating(data)

        def body(carry):
            k, _, _ = carry
            return (k + 1, *self._place(tries[k]))

        return jax.lax.while_loop(cond, body, (jnp.ones((), jnp.int32), *self._place(tries[0])))[1:]

    def reset(self, rng: jax.Array, settle=True) -> State:
        tries = self.sample_reset(rng)
        with _linesearch_loop(self.early_exit_linesearch):
            if self.reset_tries == 1:
                data, params = self._place(tries[0], settle)
            else:
                data, params = self._first_free(tries)
        zero = jnp.zeros((), jnp.float32)
        return State(pipeline_state=MjxState(data, params), obs=self._get_obs(jnp, data), reward=zero,
                     done=zero, metrics={}, info={})

    @property
    def fused_autoreset(self) -> bool:
        """Whether the auto-reset calls ``step_with_reset``: for tasks that settle their resets (MJX's vmapped
        auto-reset computes a reset at every step and keeps it where an episode ended)."""
        return self.settle_steps > 0

    def step_with_reset(self, state: State, action: jax.Array, reset_rng: jax.Array,
                        force_reset: jax.Array) -> tuple[State, State]:
        """The step and a fresh episode (``envs.mujoco_c.HostCallEnv.step_with_reset``'s contract), settled only
        where the episode ends (``force_reset``: these tasks end at the time limit only), so that a settling reset
        costs its physics steps once per episode."""
        return self.step(state, action), self.reset(reset_rng, settle=force_reset)

    def state_from_qpos_qvel(self, qpos, qvel, params=()) -> State:
        """The state at qpos/qvel (and model params), as dm_control's reset leaves it (MJX, float32)."""
        data, params = self._place(self._candidate(jnp.asarray(qpos, jnp.float32), jnp.asarray(qvel, jnp.float32),
                                                   params))
        zero = jnp.zeros((), jnp.float32)
        return State(pipeline_state=MjxState(data, params), obs=self._get_obs(jnp, data), reward=zero,
                     done=zero, metrics={}, info={})

    def _step1(self, model: mjx.Model, data: mjx.Data) -> mjx.Data:
        """dm_control's closing ``mj_step1`` (the new state's positions and frames; with ``reads_sensors`` also
        the centre-of-mass quantities and the position- and velocity-stage sensors; acceleration-stage sensors
        keep the last substep's values, as in dm_control)."""
        if not self.reads_sensors:
            return mjx.kinematics(model, data)
        data = mjx_smooth.com_pos(model, mjx_smooth.kinematics(model, data))
        data = mjx_smooth.com_vel(model, mjx_sensor.sensor_pos(model, data))
        return mjx_sensor.sensor_vel(model, data)

    def step(self, state: State, action: jax.Array) -> State:
        ctrl = self.scale_action(jnp.clip(jnp.asarray(action, jnp.float32), -1.0, 1.0))
        ps = state.pipeline_state
        model = self._model(ps.params)
        with _linesearch_loop(self.early_exit_linesearch):
            data = jax.lax.fori_loop(0, self.frame_skip, lambda _, d: mjx.step(model, d), ps.data.replace(ctrl=ctrl))
        data = self._step1(model, data)
        obs = self._get_obs(jnp, data)
        reward = self._reward(jnp, data, ctrl)
        return state.replace(pipeline_state=ps.replace(data=data), obs=obs, reward=jnp.asarray(reward, jnp.float32),
                             done=jnp.zeros((), jnp.float32), metrics={})
