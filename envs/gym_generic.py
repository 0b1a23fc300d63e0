"""Any gymnasium MuJoCo task on MuJoCo's C engine inside the program: ``gym:<Id>`` (``physics='mujoco'`` only).

``envs.make("gym:Walker2d-v5", physics="mujoco")`` (``--env=gym:Walker2d-v5``) runs gymnasium's registered
env ``Walker2d-v5`` (any ``gymnasium.envs.mujoco.MujocoEnv`` subclass: v4 and v5 tasks, or one a ``--plugin``
registers) with gymnasium's own observation, reward, termination, reward components and reset, by calling
gymnasium's own Python code on the host. The six built-in tasks keep their own definitions
(``envs/gym_mujoco.py``, on both engines); this is the path for every other task.

How it is exact
---------------
The host holds one gymnasium env instance (``gymnasium.make(id, **kwargs).unwrapped``) and nothing between
calls but that scratch. For each env of the batch, a call rebuilds the instance's ``MjData`` from the env's
carried words, runs gymnasium's own ``step`` (or ``reset``) on it, and writes the new words back. Carrying
only the integration state (``mj_getState(mjSTATE_INTEGRATION)``, what ``envs/mujoco_c.py`` carries for the
built-in tasks) would not do: gymnasium's ``step`` reads *derived* fields before it simulates (Ant-v5's
``xpos`` of the torso, Humanoid-v5's ``xipos`` for the centre of mass), and those are what the previous step's
last ``mj_step`` left, computed at the state one substep *before* the current one. So the words are a
*replay record*, one float64 row per env:

* ``[0, S]``: a fresh episode at integration state ``S``; rebuilt as gymnasium's ``reset`` leaves ``MjData``:
  ``mj_resetData``, ``mj_setState(S)``, ``mj_forward``;
* ``[1, P]``: after a step, ``P`` the integration state before the step's *last* ``mj_step``; rebuilt as
  gymnasium's ``do_simulation`` leaves it: ``mj_resetData``, ``mj_setState(P)``, one ``mj_step``,
  ``mj_rnePostConstraint``.

Every field that ``mj_step``/``mj_forward`` (and ``mj_rnePostConstraint``) compute is then gymnasium's to the
bit, whatever the env reads. ``P`` is captured by replacing the instance's ``_step_mujoco_simulation``
(gymnasium's ``do_simulation`` core: ``ctrl``, ``mj_step`` x frame_skip, ``mj_rnePostConstraint``) with the
same calls split before the last ``mj_step`` (``mj_step(nstep=k)`` is ``k`` calls of ``mj_step``). The cost is
one extra ``mj_step`` per env step, plus gymnasium's Python step per env. The row is float64, carried bit for
bit as uint32 words in the JAX state, so checkpoints, bit-for-bit resume and the rest work as for the built-in
tasks.

Threads: one by default (``--physics-threads`` or ``$METAPG_PHYSICS_THREADS`` set another count). With more, the
host holds one gymnasium instance per thread and each thread steps a contiguous slice of the batch (``mj_step``
releases the GIL, gymnasium's Python around it does not: measured, two threads slowed ``gym:Walker2d-v5`` down,
docs/performance.md#physics-threads). Each env is rebuilt from its own row, so which instance steps it changes
nothing: the numbers are one thread's bit for bit (tests/test_gym_tasks.py).

Observations and rewards reach the program as float32 casts of gymnasium's float64 numbers; the reward
components are the scalar entries of gymnasium's ``info`` (those of a probe step at construction). Actions
in [-1, 1] are mapped onto the actuators' ``ctrlrange`` in float64 on the host (as the built-in tasks), and
gymnasium's step gets those controls. ``done`` is gymnasium's ``terminated``; the unwrapped env's own
``truncated`` (False for gymnasium's MuJoCo envs) is not used: the time limit is ``envs.wrappers``' with
gymnasium's registered ``max_episode_steps``.

Resets: gymnasium's own ``reset(seed=s)`` on the host, with a 64-bit ``s`` drawn in the program from the
env's PRNG key (``jax.random.bits``). The initial states are then gymnasium's distribution exactly, and
gymnasium's own draws for that seed (the built-in tasks draw their reset noise with JAX's PRNG instead).

Names: ``gym:<Id>`` or ``gym:<Id>(k=v, ...)``, keyword arguments of ``gymnasium.make`` written as Python
keyword arguments with literal values (numbers, ``True``/``False``/``None``, quoted strings, tuples; ``inf``
and ``nan``), e.g. ``gym:Ant-v5(ctrl_cost_weight=0.1, healthy_z_range=(0.3, inf))``. The keyword arguments
are part of the task's name, so config.json, the run's label and ``--resume`` carry them.

MJX is refused: the task's math here is gymnasium's Python code run on the host, which only the host-call
engine can call; MJX traces the task into the program, which needs the task written in JAX (the built-in
tasks are, in ``envs/gym_mujoco.py``).
"""

from __future__ import annotations

import numbers
import os
import threading
from typing import Any

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from envs.gym_names import make_gymnasium_env, parse_name
from envs.host_call import THREADS_VARIABLE, resolve_threads
from envs.mujoco_c import STATE_SPEC, HostCallEnv, pack_step

__all__ = ["GymnasiumCEnv", "GymnasiumHost"]


def _scalar(value: Any) -> bool:
    return np.ndim(value) == 0 and isinstance(np.asarray(value).item(), numbers.Number)


class _Replayer:
    """One gymnasium env instance and the replay of a row on it (the module docstring): gymnasium's
    ``do_simulation`` core split before its last ``mj_step``. A host holds one per thread."""

    def __init__(self, name: str, overrides: dict):
        from gymnasium.envs.mujoco import MujocoEnv

        self.env = env = make_gymnasium_env(name, **overrides)
        if type(env)._step_mujoco_simulation is not MujocoEnv._step_mujoco_simulation:
            raise ValueError(f"{name}: {type(env).__name__} overrides MujocoEnv._step_mujoco_simulation; the "
                             f"C-engine path replays gymnasium's own")
        self.model, self.data = env.model, env.data
        self.before_last = np.empty(mujoco.mj_stateSize(self.model, STATE_SPEC))
        self.simulated = 0
        env._step_mujoco_simulation = self._simulate

    def _simulate(self, ctrl, n_frames) -> None:
        """``MujocoEnv._step_mujoco_simulation`` (ctrl, ``mj_step`` x n_frames, ``mj_rnePostConstraint``),
        keeping the integration state before the last ``mj_step``."""
        m, d = self.model, self.data
        d.ctrl[:] = ctrl
        if n_frames > 1:
            mujoco.mj_step(m, d, nstep=n_frames - 1)
        mujoco.mj_getState(m, d, self.before_last, STATE_SPEC)
        mujoco.mj_step(m, d)
        mujoco.mj_rnePostConstraint(m, d)
        self.simulated += 1

    def get_state(self) -> np.ndarray:
        out = np.empty(len(self.before_last))
        mujoco.mj_getState(self.model, self.data, out, STATE_SPEC)
        return out

    def restore(self, row: np.ndarray) -> None:
        """The instance's ``MjData`` as gymnasium left it, from a replay row (module docstring)."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        mujoco.mj_setState(m, d, row[1:], STATE_SPEC)
        if row[0] == 0.0:
            mujoco.mj_forward(m, d)
        else:
            mujoco.mj_step(m, d)
            mujoco.mj_rnePostConstraint(m, d)

    def reset_one(self, seed: int) -> tuple[np.ndarray, np.ndarray]:
        obs, _ = self.env.reset(seed=int(seed))
        return np.concatenate([[0.0], self.get_state()]), obs


class GymnasiumHost:
    """The host side of a ``gym:`` task (see the module docstring): gymnasium's env, rebuilt from each env's
    replay row before its own ``step`` / ``reset`` runs; with ``threads`` above 1, one instance per thread,
    each stepping a slice of the batch.

    ``step`` / ``reset`` / ``integration_state`` are plain numpy functions (float64; used by the callbacks and
    by tests that compare with gymnasium); ``step_words`` / ``reset_words`` are the callbacks' entry points
    (``envs.mujoco_c.HostCallEnv``'s host protocol).
    """

    def __init__(self, name: str, threads: int | None = None, **overrides):
        from gymnasium import spaces

        # One thread unless asked: measured, threads slow a gym: task down (gymnasium's Python holds the GIL
        # around each mj_step; docs/performance.md#physics-threads).
        self.threads = resolve_threads(1 if threads is None and not os.environ.get(THREADS_VARIABLE) else threads)
        self._name, self._overrides = name, overrides
        first = _Replayer(name, overrides)
        self._replayers = [first]   # more, one per thread, on the first call that uses them
        self._pool = None
        self.env, self.model, self.data = first.env, first.model, first.data
        self.nstate = mujoco.mj_stateSize(self.model, STATE_SPEC)
        self.nrow = 1 + self.nstate  # [mode | integration state]
        self.nq, self.nv, self.nu = self.model.nq, self.model.nv, self.model.nu
        env = first.env
        obs_space, act_space = env.observation_space, env.action_space
        if not (isinstance(obs_space, spaces.Box) and len(obs_space.shape) == 1):
            raise ValueError(f"{name}: the observation space {obs_space} is not a flat Box")
        if not (isinstance(act_space, spaces.Box) and act_space.shape == (self.nu,)):
            raise ValueError(f"{name}: the action space {act_space} is not a Box of the {self.nu} actuators")
        self.obs_size = int(obs_space.shape[0])
        # [-1, 1] -> the actuators' ctrlrange in float64 (gymnasium's action space is that range in float32);
        # an env with another action space: its bounds.
        ctrlrange = np.array(self.model.actuator_ctrlrange, np.float64)
        if (np.array_equal(act_space.low, ctrlrange[:, 0].astype(np.float32))
                and np.array_equal(act_space.high, ctrlrange[:, 1].astype(np.float32))):
            self.low, self.high = ctrlrange[:, 0], ctrlrange[:, 1]
        else:
            self.low, self.high = np.float64(act_space.low), np.float64(act_space.high)
        if not (np.isfinite(self.low).all() and np.isfinite(self.high).all() and (self.low < self.high).all()):
            raise ValueError(f"{name}: the action space {act_space} has no finite range to map [-1, 1] onto")
        self._lock = threading.Lock()
        try:
            self.metric_keys = self._probe(name)
        except ValueError:
            raise
        except Exception as err:  # e.g. a keyword argument of the wrong type, used only when it steps
            raise ValueError(f"{name}: gymnasium's env failed on a probe step: "
                             f"{type(err).__name__}: {err}".splitlines()[0]) from None
        self.w_state = 2 * self.nrow
        self.w_step_out = self.w_state + 2 * self.obs_size + 2 + len(self.metric_keys)
        self.w_reset_out = self.w_state + self.obs_size

    def _probe(self, name: str) -> tuple[str, ...]:
        """One reset and two steps: the replay rebuilds gymnasium's state, and the scalar ``info`` entries
        (the reward components and the like) that become the state's ``metrics``."""
        r = self._replayers[0]
        rows = self.reset(np.array([0]))[0]
        info = {}
        for action in (np.zeros((1, self.nu)), np.full((1, self.nu), 0.5)):
            r.simulated = 0
            r.restore(rows[0])
            _, _, _, _, info = r.env.step(self.scale_action(action)[0])
            if r.simulated == 0:
                raise ValueError(f"{name}: its step does not simulate through MujocoEnv.do_simulation")
            state = r.get_state()
            rows = np.concatenate([[1.0], r.before_last])[None]
            r.restore(rows[0])
            if not np.array_equal(r.get_state(), state):
                raise ValueError(f"{name}: replaying its step's last mj_step does not give its state")
        return tuple(k for k, v in info.items() if _scalar(v))

    def _each(self, n: int, work) -> None:
        """``work(replayer, ids)`` over the batch's n envs: one contiguous slice of ids per thread (at most n),
        the slices stepped at once on the thread pool; one slice runs on the calling thread."""
        k = min(self.threads, n)
        if k <= 1:
            work(self._replayers[0], range(n))
            return
        while len(self._replayers) < k:
            self._replayers.append(_Replayer(self._name, self._overrides))
        if self._pool is None:
            from concurrent.futures import ThreadPoolExecutor

            self._pool = ThreadPoolExecutor(self.threads, thread_name_prefix="gym-physics")
        bounds = np.linspace(0, n, k + 1).astype(int)
        futures = [self._pool.submit(work, self._replayers[j], range(bounds[j], bounds[j + 1])) for j in range(k)]
        for f in futures:
            f.result()

    # -- numpy API (float64) ------------------------------------------------------

    def scale_action(self, action: np.ndarray) -> np.ndarray:
        """Actions in [-1, 1] -> controls (float64), as ``GymMujocoEnv.scale_action`` for the built-in tasks."""
        return self.low + (np.asarray(action, np.float64) + 1.0) * 0.5 * (self.high - self.low)

    def reset(self, seeds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """gymnasium's ``reset(seed=s)`` for each of ``seeds`` (n,): (replay rows (n, nrow), obs (n, obs))."""
        seeds = np.asarray(seeds).reshape(-1)
        rows, obs = np.empty((len(seeds), self.nrow)), np.empty((len(seeds), self.obs_size))

        def work(r: _Replayer, ids) -> None:
            for i in ids:
                rows[i], obs[i] = r.reset_one(int(seeds[i]))

        with self._lock:
            self._each(len(seeds), work)
        return rows, obs

    def integration_state(self, rows: np.ndarray) -> np.ndarray:
        """The integration state (``mj_getState``, mjSTATE_INTEGRATION) each replay row stands for (n, nstate)."""
        rows = np.asarray(rows, np.float64).reshape(-1, self.nrow)
        out = np.empty((len(rows), self.nstate))
        r = self._replayers[0]
        with self._lock:
            for i, row in enumerate(rows):
                r.restore(row)
                out[i] = r.get_state()
        return out

    def step(self, rows: np.ndarray, action: np.ndarray, reset_seeds=None, force_reset=None) -> dict:
        """One env step of n envs from replay rows (n, nrow) with actions (n, nu) in [-1, 1] (mapped onto
        ctrlrange in float64; ``ctrl`` in the result): gymnasium's own ``step`` of each.

        Returns a dict of float64 arrays: ``next_obs``, ``reward``, ``terminated`` (bool) and ``metrics`` (the
        scalar ``info`` entries), all of the step; ``rows`` and ``obs``, the state after it. With
        ``reset_seeds`` (n,), the envs that ended (terminated, or ``force_reset``) are reset with gymnasium's
        ``reset(seed=reset_seeds[i])``: their ``rows`` and ``obs`` are the fresh episode's.
        """
        rows = np.asarray(rows, np.float64).reshape(-1, self.nrow)
        n = len(rows)
        ctrl = self.scale_action(np.asarray(action).reshape(n, self.nu))
        next_obs, reward = np.empty((n, self.obs_size)), np.empty(n)
        terminated = np.zeros(n, bool)
        metrics = {k: np.zeros(n) for k in self.metric_keys}
        new_rows = np.empty((n, self.nrow))
        new_rows[:, 0] = 1.0
        obs = next_obs.copy() if reset_seeds is not None else next_obs
        done = np.zeros(n, bool) if reset_seeds is None else np.asarray(force_reset, bool).reshape(n)

        def work(r: _Replayer, ids) -> None:
            for i in ids:
                r.restore(rows[i])
                o, rew, term, _, info = r.env.step(ctrl[i])
                next_obs[i], reward[i], terminated[i] = o, rew, term
                for k in self.metric_keys:
                    metrics[k][i] = info.get(k, 0.0)
                new_rows[i, 1:] = r.before_last
                if reset_seeds is None:
                    continue
                if term or done[i]:
                    new_rows[i], obs[i] = r.reset_one(int(reset_seeds[i]))
                else:
                    obs[i] = o

        with self._lock:
            self._each(n, work)
        return {"next_obs": next_obs, "reward": reward, "terminated": terminated, "metrics": metrics,
                "rows": new_rows, "obs": obs, "ctrl": ctrl}

    # -- callbacks (packed uint32 words) --------------------------------------------

    @staticmethod
    def _seeds(words: np.ndarray) -> np.ndarray:
        """(n, 2) uint32 [low, high] -> (n,) Python ints in [0, 2**64)."""
        return np.array([int(lo) | (int(hi) << 32) for lo, hi in words], dtype=object)

    def reset_words(self, words: np.ndarray) -> np.ndarray:
        """[seed uint32 x 2] per env -> [replay row | obs f32]."""
        words = np.asarray(words)
        lead = words.shape[:-1]
        rows, obs = self.reset(self._seeds(words.reshape(-1, 2)))
        out = np.empty((len(rows), self.w_reset_out), np.uint32)
        out[:, :self.w_state] = rows.view(np.uint32)
        out.view(np.float32)[:, self.w_state:] = obs
        return out.reshape(*lead, self.w_reset_out)

    def step_words(self, words: np.ndarray, fused: bool) -> np.ndarray:
        """[replay row | action f32 (| seed uint32 x 2 | force_reset f32)] per env ->
        [replay row | next_obs f32 | obs f32 | reward f32 | terminated f32 | metrics f32]."""
        words = np.asarray(words)
        lead = words.shape[:-1]
        flat = words.reshape(-1, words.shape[-1])
        ws, nu, no = self.w_state, self.nu, self.obs_size
        rows = np.ascontiguousarray(flat[:, :ws]).view(np.float64)
        f = flat[:, ws:].view(np.float32)
        if fused:
            r = self.step(rows, f[:, :nu], self._seeds(flat[:, ws + nu:ws + nu + 2]), f[:, nu + 2] > 0.5)
        else:
            r = self.step(rows, f[:, :nu])
        out = np.empty((len(flat), self.w_step_out), np.uint32)
        out[:, :ws] = r["rows"].view(np.uint32)
        pack_step(out, r, ws, no, self.metric_keys)
        return out.reshape(*lead, self.w_step_out)


class GymnasiumCEnv(HostCallEnv):
    """A ``gym:`` task (gymnasium's own env, any MuJoCo one) on MuJoCo's C engine (Brax ``Env`` interface).

    The contract of the built-in tasks (actions in [-1, 1], ``done`` = gymnasium's terminated, float32
    ``obs``/``reward``/``metrics``, empty ``info`` at reset); ``pipeline_state`` is the float64 replay row
    (module docstring) as uint32 words (``GymnasiumHost.nrow`` * 2).
    """

    def __init__(self, name: str, threads: int | None = None, **overrides):
        self.name = name
        self.host = GymnasiumHost(name, threads, **overrides)
        self.gym_id = parse_name(name)[0]
        self.mj_model = self.host.model
        self.frame_skip = int(self.host.env.frame_skip)
        self.dt = float(self.host.env.dt)

    def _reset_words(self, rng: jax.Array) -> jax.Array:
        """The seed of gymnasium's ``reset(seed=...)``: 64 random bits from the key, as two uint32 words."""
        return jax.random.bits(rng, (2,), jnp.uint32)

    def reset_seed(self, rng: jax.Array) -> int:
        """The seed ``reset(rng)`` hands gymnasium (outside jit; for comparisons with gymnasium)."""
        lo, hi = np.asarray(self._reset_words(rng)).tolist()
        return lo | (hi << 32)
