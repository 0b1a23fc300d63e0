"""MuJoCo's C engine inside the compiled program (``physics='mujoco'``).

The gymnasium v5 tasks of ``envs/gym_mujoco.py`` (their observation, reward,
termination, reset noise and action scaling, written once) stepped by
MuJoCo's own C library instead of MJX. Every env step of every seed is one
host call (``host_call`` below: ``jax.pure_callback``) that receives the
whole batch (seeds x envs arrive as one array) and steps it with
``mujoco.batch.Batch``, MuJoCo's thread pool over many simulations of one
model. Its results are bit-identical to a loop of ``mj_step`` over one
``MjData`` per simulation at any thread count (MuJoCo's documentation, and
tests/test_physics.py checks the loop against gymnasium).

What lives where:

* **The physics state is in the JAX state.** ``State.pipeline_state`` is the
  complete integration state (``mj_getState`` with ``mjSTATE_INTEGRATION``:
  time, qpos, qvel, act, the solver's warm start, ctrl, applied forces, ...)
  as float64, carried bit for bit as pairs of uint32 words, so x64 stays off
  for the whole program. A step from a stored state is gymnasium's next step.
  Checkpoints, bit-for-bit resume, chunked == single scan, sharding and the
  NaN guard see a plain uint32 array.
* **The task math runs on the host in float64.** Observations, rewards,
  termination and reward components are computed by the task's own methods
  with ``numpy`` in float64 (the same functions MJX traces with ``jax.numpy``
  in float32), so they equal gymnasium's to the bit; the program gets them as
  float32 (what the networks see; ``State.obs`` and ``reward`` are float32 as
  with MJX).
* **Nothing persists on the host between calls** but scratch: one
  ``mujoco.batch.Batch`` (its ``MjData`` and thread pool) per batch size,
  whose state rows every call overwrites from its input. A lock serialises
  calls that share a scratch batch (e.g. callbacks of several devices).

The host call itself (``jax.pure_callback``, one packed uint32 array each way) is ``envs/host_call.py``.

One callback per env step: the auto-reset is fused into the step
(``step_with_reset``): the host steps every env, and envs that ended (their
task terminated them, or the time limit ``force_reset`` says so) are reset
in the same call (``mj_resetData``, the new qpos/qvel, ``mj_forward``, as
gymnasium's ``reset``). Reset noise is drawn in the program with JAX's PRNG
(float32, as with MJX: gymnasium's distribution, not its draws).

The program side (``HostCallEnv``: reset, step and the fused step as host calls on state words) also
carries any gymnasium MuJoCo env, ``gym:<Id>``, whose host side runs gymnasium's own code
(``envs/gym_generic.py``).

The C engine runs on the host CPU even when JAX runs on a GPU: every step
then crosses between device and host. MJX is the engine that scales on
accelerators; this one is for CPUs (measured speeds: docs/performance.md, "Physics engines").
"""

from __future__ import annotations

import threading
import types

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from brax.envs.base import Env, State
from mujoco import batch as mj_batch

from envs.host_call import _floats, _words, host_call, resolve_threads

__all__ = ["HostCallEnv", "MujocoCEnv", "HostPhysics", "STATE_SPEC"]

STATE_SPEC = mujoco.mjtState.mjSTATE_INTEGRATION


def pack_step(out: np.ndarray, r: dict, ws: int, no: int, metric_keys) -> None:
    """Writes a host step's results after the ``ws`` state words of each row of ``out`` (uint32 words): next_obs,
    obs, reward, terminated and the metrics, as float32 (the step call's output layout)."""
    o = out.view(np.float32)
    o[:, ws:ws + no] = r["next_obs"]
    o[:, ws + no:ws + 2 * no] = r["obs"]
    k = ws + 2 * no
    o[:, k] = r["reward"]
    o[:, k + 1] = r["terminated"]
    for i, name in enumerate(metric_keys):
        o[:, k + 2 + i] = r["metrics"][name]


class HostPhysics:
    """The host side: steps and resets batches of one task's simulations in float64.

    ``step`` and ``reset`` are plain numpy functions (used by the callbacks and
    by tests that compare with gymnasium); ``step_words`` / ``reset_words`` are
    the callbacks' entry points, one packed uint32 array in and one out.

    A state row is the integration state followed by the task's per-env model entries
    (``task.model_params``: none for gymnasium's tasks; e.g. the target of DeepMind Control's Reacher),
    which are written into the batch's per-simulation copy of those model fields before every call.
    A reset gets ``task.reset_tries`` candidates per env and keeps the first without contacts after
    ``mj_forward`` (the last one if all have some; one: that one), then settles it (``task.settle_steps``)."""

    def __init__(self, task, threads: int | None = None):
        self.task = task
        self.model = task.mj_model
        self.frame_skip = int(task.frame_skip)
        self.threads = resolve_threads(threads)
        self.nstate = mujoco.mj_stateSize(self.model, STATE_SPEC)
        self.nq, self.nv, self.nu = self.model.nq, self.model.nv, self.model.nu
        self.params, self.tries = tuple(task.model_params), int(task.reset_tries)
        self.nparam, self.stage = len(self.params), int(task.step_stage)
        self.obs_size = int(task.observation_size)
        self.metric_keys = tuple(task._metric_keys)
        self.fields = tuple(task.derived_fields)
        # The integration state after mj_resetData (time 0, qpos0, zero velocities, controls, warm start, ...).
        data = mujoco.MjData(self.model)
        mujoco.mj_resetData(self.model, data)
        self.reset_row = np.empty(self.nstate)
        mujoco.mj_getState(self.model, data, self.reset_row, STATE_SPEC)
        self._scratch: dict[int, _Scratch] = {}
        self._lock = threading.Lock()
        # Packed widths (uint32 words per env) of the callbacks' inputs and outputs.
        self.w_state = 2 * (self.nstate + self.nparam)
        self.w_reset_in = self.tries * (self.nq + self.nv + self.nparam)
        self.w_step_out = self.w_state + 2 * self.obs_size + 2 + len(self.metric_keys)
        self.w_reset_out = self.w_state + self.obs_size

    def _get(self, nsim: int) -> "_Scratch":
        s = self._scratch.get(nsim)
        if s is None:
            s = self._scratch[nsim] = _Scratch(self, nsim)
        return s

    # -- numpy API (float64) ------------------------------------------------------

    def reset(self, qpos: np.ndarray, qvel: np.ndarray, params=None):
        """States at (n, nq) / (n, nv) float64 qpos/qvel (and (n, nparam) model params; default 0), taken as
        they are: returns (state rows (n, nstate + nparam), obs (n, obs))."""
        qpos = np.asarray(qpos, np.float64).reshape(-1, self.nq)
        qvel = np.asarray(qvel, np.float64).reshape(-1, self.nv)
        params = np.zeros((len(qpos), self.nparam)) if params is None else np.asarray(params, np.float64)
        with self._lock:
            s = self._get(len(qpos))
            s.reset(None, np.concatenate([qpos, qvel, params.reshape(len(qpos), -1)], axis=-1)[:, None])
            return s.rows(), s.obs()

    def step(self, rows: np.ndarray, action: np.ndarray, reset_tries=None, force_reset=None):
        """One env step of n simulations from state rows (n, nstate + nparam) with actions (n, nu) in [-1, 1]
        (mapped onto ctrlrange in float64 as the task's ``scale_action``; ``ctrl`` in the result), in float64.

        Returns a dict of float64 arrays: ``next_obs``, ``reward``, ``terminated`` (bool) and the
        task's reward components (``metrics``), all of the step; and ``rows`` and ``obs``, the state
        after it. With ``reset_tries`` (n, tries, nq + nv + nparam), the envs that ended (terminated, or
        ``force_reset``) are reset to them: their ``rows`` and ``obs`` are the reset state's.
        """
        rows = np.asarray(rows, np.float64).reshape(-1, self.nstate + self.nparam)
        with self._lock:
            s = self._get(len(rows))
            s.batch.state[:] = rows[:, :self.nstate]
            s.params[:] = rows[:, self.nstate:]
            out = s.step(action, reset_tries, force_reset)
            out["rows"] = s.rows()
            return out

    # -- callbacks (packed uint32 words) --------------------------------------------

    def reset_words(self, words: np.ndarray) -> np.ndarray:
        """[tries x (qpos | qvel | params) f32] per env -> [state | obs f32]."""
        words = np.asarray(words)
        lead = words.shape[:-1]
        flat = words.reshape(-1, words.shape[-1]).view(np.float32)
        with self._lock:
            s = self._get(len(flat))
            s.reset(None, flat.reshape(len(flat), self.tries, -1))
            rows, obs = s.rows(), s.obs()
        out = np.empty((len(rows), self.w_reset_out), np.uint32)
        out[:, :self.w_state] = rows.view(np.uint32)
        out.view(np.float32)[:, self.w_state:] = obs
        return out.reshape(*lead, self.w_reset_out)

    def step_words(self, words: np.ndarray, fused: bool) -> np.ndarray:
        """[state | action f32 (| reset tries f32 | force_reset f32)] per env ->
        [state | next_obs f32 | obs f32 | reward f32 | terminated f32 | metrics f32]."""
        words = np.asarray(words)
        lead = words.shape[:-1]
        flat = words.reshape(-1, words.shape[-1])
        n, ws, no, wi = len(flat), self.w_state, self.obs_size, 2 * self.nstate
        f = flat[:, ws:].view(np.float32)
        nu, wr = self.nu, self.w_reset_in
        with self._lock:
            s = self._get(n)
            s.words[:] = flat[:, :wi]
            s.params[:] = flat[:, wi:ws].view(np.float64)
            if fused:
                r = s.step(f[:, :nu], f[:, nu:nu + wr].reshape(n, self.tries, -1), f[:, nu + wr] > 0.5)
            else:
                r = s.step(f[:, :nu])
            out = np.empty((n, self.w_step_out), np.uint32)
            out[:, :wi] = s.words
            out[:, wi:ws] = s.params.view(np.uint32)
        pack_step(out, r, ws, no, self.metric_keys)
        return out.reshape(*lead, self.w_step_out)


class _Scratch:
    """One batch size's scratch: a ``mujoco.batch.Batch`` and live views of its fields.

    Holds nothing between calls that a call does not first overwrite (the state rows and model params).
    """

    def __init__(self, host: HostPhysics, nsim: int):
        self.task, self.frame_skip, self.stage = host.task, host.frame_skip, host.stage
        self.reset_row, self.fields = host.reset_row, host.fields
        self.nq, self.nv = host.nq, host.nv
        self.batch = b = mj_batch.Batch(host.model, nsim, nthread=min(host.threads, nsim))
        self.words = b.state.view(np.uint32)
        self.qpos, self.ctrl = b.bind("qpos"), b.bind("ctrl")
        # The model params (nsim, nparam) and where they go: flat views of per-simulation model fields.
        self.params = np.zeros((nsim, host.nparam))
        self._targets = [(b.expand(field).reshape(nsim, -1), index) for field, index in host.params]
        self.ncon = b.bind("ncon") if host.tries > 1 else None
        # What the task math reads, as (n, ...) float64 arrays.
        self.view = types.SimpleNamespace(qpos=self.qpos, qvel=b.bind("qvel"),
                                          **{name: b.bind(name) for name in host.fields})

    def rows(self) -> np.ndarray:
        """The state rows (a copy): integration state, model params."""
        return np.concatenate([self.batch.state, self.params], axis=-1)

    def _write_params(self) -> None:
        for j, (target, index) in enumerate(self._targets):
            target[:, index] = self.params[:, j]

    def obs(self) -> np.ndarray:
        return self.task._get_obs(np, self.view)

    def reset(self, ids, tries) -> None:
        """gymnasium's reset of simulations ``ids`` (None: all) to ``tries`` (len(ids), tries, nq + nv + nparam):
        mj_resetData (the reset row written into the state rows), set qpos/qvel and the model params, mj_forward
        (only for tasks that read derived fields or reject: it changes no state, and a batch call costs ~50-100
        us); of several tries, the first without contacts; then the task's settling steps, if any."""
        rows, nq, nv = self.batch.state, self.nq, self.nv
        ids = np.arange(len(rows)) if ids is None else ids
        pick = np.arange(len(ids))  # rows of ``tries`` still to place, and their simulations
        for k in range(tries.shape[1]):
            sims, cand = ids[pick], tries[pick, k]
            rows[sims] = self.reset_row
            self.qpos[sims], self.view.qvel[sims] = cand[:, :nq], cand[:, nq:nq + nv]
            self.params[sims] = cand[:, nq + nv:]
            self._write_params()
            if self.fields or self.ncon is not None:
                self.batch.forward(sims)
            if self.ncon is None or k == tries.shape[1] - 1:
                break
            pick = pick[self.ncon[sims] > 0]
            if not len(pick):
                break
        if self.task.settle_steps:  # DeepMind Control's cheetah: its draw settles (DmcTask.settle), mj_forward
            rows[ids] = self.task.settle(rows[ids])
            self.batch.forward(ids)

    def step(self, action, reset_tries=None, force_reset=None) -> dict:
        """The step of every simulation from the state rows as they are (see ``HostPhysics.step``)."""
        self._write_params()
        self.ctrl[:] = self.task.scale_action(action, np)
        before = types.SimpleNamespace(qpos=self.qpos.copy())
        self.batch.step(nstep=self.frame_skip, stage=self.stage)
        next_obs = self.task._get_obs(np, self.view)
        reward, terminated, metrics = self.task._reward_done(np, before, self.view, self.ctrl, next_obs)
        out = {"next_obs": next_obs, "reward": reward, "terminated": terminated, "metrics": metrics,
               "obs": next_obs, "ctrl": self.ctrl.copy()}
        if reset_tries is not None:
            done = terminated | force_reset
            if done.any():
                ids = np.flatnonzero(done)
                self.reset(ids, reset_tries[ids])
                obs = next_obs.copy()
                obs[ids] = self.obs()[ids]  # (all rows at once: cheaper than gathering the fields)
                out["obs"] = obs
        return out


class HostCallEnv(Env):
    """The program side of a task whose physics and task math run on the host (Brax ``Env`` interface):
    the state's ``pipeline_state`` is the host's state words, and reset, step and the fused step with
    auto-reset are one host call each, through ``host_call``.

    Subclasses set ``host`` (``HostPhysics`` here, ``envs.gym_generic.GymnasiumHost`` for a ``gym:`` task),
    which provides ``obs_size``, ``nu``, ``metric_keys``, the packed widths ``w_state`` / ``w_step_out`` /
    ``w_reset_out`` and the callbacks ``reset_words(words)`` and ``step_words(words, fused)``; and
    ``_reset_words(rng)``, the words that ask the host for one fresh episode.
    """

    # The auto-reset wrapper calls step_with_reset: one host call per step instead of two.
    fused_autoreset = True
    host: "HostPhysics"

    @property
    def observation_size(self) -> int:
        return self.host.obs_size

    @property
    def action_size(self) -> int:
        return self.host.nu

    @property
    def backend(self) -> str:
        return "mujoco"

    def _reset_words(self, rng: jax.Array) -> jax.Array:
        """The host's input that resets one env (the part of ``reset_words``' input for one env)."""
        raise NotImplementedError

    def _state(self, words, obs, reward, done, metrics) -> State:
        return State(pipeline_state=words, obs=obs, reward=reward, done=done, metrics=metrics, info={})

    def _fresh(self, out: jax.Array) -> State:
        """The state of a fresh episode from ``reset_words``' output [state | obs f32]."""
        h = self.host
        zero = jnp.zeros((), jnp.float32)
        return self._state(out[:h.w_state], _floats(out[h.w_state:]), zero, zero,
                           {k: zero for k in h.metric_keys})

    def reset(self, rng: jax.Array) -> State:
        h = self.host
        return self._fresh(host_call(h.reset_words, self._reset_words(rng), h.w_reset_out))

    def _call_step(self, state: State, action: jax.Array, reset=None):
        h = self.host
        # Clipped here (exact); mapped onto ctrlrange on the host, in float64 (no float32 rounding,
        # and no XLA fusion choice can change the controls).
        action = jnp.clip(jnp.asarray(action, jnp.float32), -1.0, 1.0)
        parts = [state.pipeline_state, _words(action)]
        if reset is not None:
            reset_words, force = reset
            parts += [reset_words, _words(force.astype(jnp.float32)[None])]
        fused = reset is not None
        out = host_call(lambda w: h.step_words(w, fused), jnp.concatenate(parts, axis=-1), h.w_step_out)
        words, f = out[:h.w_state], _floats(out[h.w_state:])
        n = h.obs_size
        metrics = {k: f[2 * n + 2 + i] for i, k in enumerate(h.metric_keys)}
        # As MJX's step: ``info`` (the wrappers') passes through.
        stepped = state.replace(pipeline_state=words, obs=f[:n], reward=f[2 * n], done=f[2 * n + 1],
                                metrics=metrics)
        return stepped, f[n:2 * n]

    def step(self, state: State, action: jax.Array) -> State:
        return self._call_step(state, action)[0]

    def step_with_reset(self, state: State, action: jax.Array, reset_rng: jax.Array,
                        force_reset: jax.Array) -> tuple[State, State]:
        """The step and, where it ended the episode (terminated, or ``force_reset``), a fresh episode.

        Returns ``(stepped, fresh)``: ``stepped`` is the step's state as ``step`` returns it but
        with ``pipeline_state`` already the fresh episode's where it ended; ``fresh`` has the state
        and first observation of the new episode there (elsewhere the stepped ones). One host call.
        """
        stepped, obs = self._call_step(state, action, (self._reset_words(reset_rng), force_reset))
        zero = jnp.zeros((), jnp.float32)
        fresh = self._state(stepped.pipeline_state, obs, zero, zero, {k: zero for k in self.host.metric_keys})
        return stepped, fresh


class MujocoCEnv(HostCallEnv):
    """A gymnasium task of ``envs.gym_mujoco`` stepped by MuJoCo's C engine (Brax ``Env`` interface).

    Same contract as the MJX task it wraps (actions in [-1, 1], ``done`` = gymnasium's terminated,
    float32 ``obs``/``reward``/``metrics``, empty ``info`` at reset); ``pipeline_state`` is the
    float64 integration state as uint32 words (``HostPhysics.nstate`` * 2).
    """

    def __init__(self, task, threads: int | None = None):
        self.task = task
        self.host = HostPhysics(task, threads)
        self.mj_model = task.mj_model
        self.gym_id = task.gym_id
        self.frame_skip = task.frame_skip
        self.dt = task.dt

    # -- the program side -----------------------------------------------------------

    def _reset_words(self, rng: jax.Array) -> jax.Array:
        """The reset's candidates drawn with the task's reset noise (``sample_reset``), as float32 words."""
        return _words(self.task.sample_reset(rng).reshape(-1))

    def state_from_qpos_qvel(self, qpos: jax.Array, qvel: jax.Array, params=None) -> State:
        """State at qpos/qvel (and model params; float32 in the program), as gymnasium's ``reset`` makes it."""
        h = self.host
        params = jnp.zeros(h.nparam, jnp.float32) if params is None else params
        row = jnp.concatenate([jnp.asarray(qpos, jnp.float32), jnp.asarray(qvel, jnp.float32),
                               jnp.asarray(params, jnp.float32)])
        words = _words(jnp.tile(row, h.tries))
        return self._fresh(host_call(h.reset_words, words, h.w_reset_out))

    # -- host helpers -----------------------------------------------------------------

    def state_from_gymnasium(self, qpos: np.ndarray, qvel: np.ndarray, params=None) -> State:
        """State at float64 qpos/qvel (and model params; e.g. copied from a gymnasium env), computed on the host
        without rounding to float32 (outside jit; one env, or a batch with a leading axis)."""
        qpos = np.asarray(qpos, np.float64)
        rows, obs = self.host.reset(qpos, qvel, params)
        lead = qpos.shape[:-1]
        zero = jnp.zeros(lead, jnp.float32)
        return self._state(jnp.asarray(rows.view(np.uint32).reshape(*lead, -1)),
                           jnp.asarray(obs.astype(np.float32).reshape(*lead, -1)), zero, zero,
                           {k: zero for k in self.host.metric_keys})
