"""The training loop: the per-seed ``TrainState`` and the ``Trainer`` that advances it.

A ``Trainer`` holds the config, the env, a *student* (the off-policy learner) and an *explorer* (who
collects the student's data); both interfaces are in ``metapg_jax.strategy``. It gives

* ``init(key) -> TrainState`` for one seed;
* ``train_chunk(state) -> (state, metrics)``: a ``lax.scan`` over
  ``cycles_per_chunk`` cycles followed by one evaluation;
* ``train(key) -> (state, metrics)``: ``init`` and a scan over all chunks, one
  program for the whole run;

and the building blocks an explorer's cycle is made of: ``store`` (buffer, normaliser, sample count),
``student_updates`` (the student's updates on replay minibatches, with an optional hook between
blocks of updates), ``random_action``, ``evaluate``. A *cycle* is the loop's ``acting_cycle`` for an
explorer that only chooses actions (the baselines' noise: ``steps_per_cycle`` steps, stored, then
``train_steps`` updates), or the explorer's own (one meta-iteration of Algorithm 1). This module imports no
strategy, only their contract (``metapg_jax.strategy``): ``metapg_jax.train.make_train`` puts the pieces together.

Both paths give the same numbers for the same key. Seeds are a vmap over keys of these functions
(``metapg_jax.seeds.vmap_seeds``); the host (``experiments.run``) jits the vmapped ``train_chunk`` once
and calls it once per evaluation interval.

The student and explorer interfaces (what the loop and the explorers use) are the base classes of
``metapg_jax.strategy``, which give every optional hook a default: the loop calls the hooks without asking
whether they are there, and a ``Trainer`` refuses a student or explorer that breaks the contract when it is
built (``strategy.check_student``, ``check_explorer``).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
from brax.envs.base import Env, State
from flax import struct

from metapg_jax import normalizer as norm_lib
from metapg_jax import replay
from metapg_jax import visits as visits_lib
from metapg_jax.config import Config
from metapg_jax.evaluate import evaluate
from metapg_jax.rollout import completed_episode_mean, rollout
from metapg_jax.seeds import per_seed_cond, vmap_seeds
from metapg_jax.strategy import ActingExplorer, Explorer, Student, check_explorer, check_student
from metapg_jax.types import Transition


@struct.dataclass
class TrainState:
    student: Any                     # the student's state (strategy.Student: .actor, ...)
    normalizer: norm_lib.NormalizerState
    buffer: replay.ReplayState
    env_state: State                 # the exploring env (episodes continue across cycles)
    explorer: Any                    # the explorer's state (NoiseState, TeacherState, ...)
    visits: visits_lib.VisitState    # bounded sample of visited states (state-visitation figure)
    key: jax.Array
    env_steps: jax.Array             # int32: stored env steps so far (the sample budget)
    updates: jax.Array               # int32: student updates so far
    cycles: jax.Array                # int32


def all_finite(params: Any) -> jax.Array:
    """NaN/inf guard, computed inside the program: is every leaf of ``params`` finite? (``Trainer.cycle`` asks it of
    what the student and the explorer guard: ``guarded_params`` of ``metapg_jax.strategy``.)

    Returned per cycle in the metrics, so the host learns of a bad seed at the
    next chunk boundary without any host sync inside the chunk.
    """
    return jnp.all(jnp.stack([jnp.all(jnp.isfinite(x)) for x in jax.tree.leaves(params)]))


def flatten_time(tree):
    """Merges the two leading axes (e.g. time x envs) of every leaf."""
    return jax.tree.map(lambda x: x.reshape((-1,) + x.shape[2:]), tree)


def train_updates(learner, student: Any, normalizer, sample, key: jax.Array, num: int):
    """``num`` updates of ``learner`` (the student) with minibatches from ``sample(key)``; returns the mean metrics."""

    def step(st, k):
        return learner.update(st, normalizer, sample(k))

    student, metrics = jax.lax.scan(step, student, jax.random.split(key, num))
    return student, jax.tree.map(jnp.mean, metrics)


@dataclasses.dataclass(frozen=True)
class Trainer:
    config: Config
    env: Env
    student: Student     # the learner
    explorer: Explorer   # an ActingExplorer (init, act, ...) or an Explorer (init, cycle)

    def __post_init__(self):
        check_student(self.student)
        check_explorer(self.explorer)

    # ------------------------------------------------------------------ init
    def init(self, key: jax.Array) -> TrainState:
        cfg = self.config
        k_student, k_env, k_explorer, key = jax.random.split(key, 4)
        student = self.student.init(k_student)
        env_state = self.env.reset(k_env)
        state = TrainState(
            student=student,
            normalizer=norm_lib.init(self.student.obs_size),
            buffer=replay.init(cfg.buffer_capacity, self.student.obs_size, self.student.action_size),
            env_state=env_state,
            explorer=None,
            visits=visits_lib.init(cfg.run.visit_samples, self.student.obs_size),
            key=key,
            env_steps=jnp.zeros((), jnp.int32),
            updates=jnp.zeros((), jnp.int32),
            cycles=jnp.zeros((), jnp.int32),
        )
        return state.replace(explorer=self.explorer.init(self, student, k_explorer))

    # ------------------------------------------------------------------ building blocks of a cycle
    def store(self, state: TrainState, transitions: Transition, source: str = "explore") -> TrainState:
        """Adds a flat batch of transitions to the buffer and the normaliser, counts them, and keeps their states
        in the visitation sample as the exploring policy's (``source='explore'``) or the student's
        (``'student'``: Algorithm 1's D1 and D2)."""
        n = transitions.reward.shape[0]
        if source not in ("explore", "student"):
            raise ValueError(f"store: source must be 'explore' or 'student', got {source!r}")
        return state.replace(
            buffer=replay.add(state.buffer, transitions),
            normalizer=norm_lib.update(state.normalizer, transitions.obs),
            env_steps=state.env_steps + n,
            visits=visits_lib.record(state.visits, **{f"{source}_obs": transitions.obs}),
        )

    def can_update(self, state: TrainState) -> jax.Array:
        """Updates start once the warm-up is over and the buffer holds a minibatch."""
        return jnp.logical_and(state.env_steps >= self.config.run.warmup_steps,
                               state.buffer.size >= self.config.ddpg.batch_size)

    def random_action(self, key: jax.Array) -> jax.Array:
        return jax.random.uniform(key, (self.student.action_size,), jnp.float32, -1.0, 1.0)

    def student_updates(self, state: TrainState, key: jax.Array, num: int, between=None, block: int = 0):
        """``num`` updates of the student on replay minibatches (skipped during warm-up).

        ``between(explorer_state, student_state, minibatch, key) -> explorer_state``, if given, runs
        before updates 0, block, 2 block, ... of the ``num`` (on a replay minibatch of its own): the
        hook through which adaptive parameter noise adapts its stddev as baselines does within each
        cycle (``t_train % param_noise_adaption_interval == 0``). The positions are static, so no
        per-update conditional is needed.
        """
        cfg = self.config
        block = block if between is not None else num
        sample = lambda k: replay.sample(state.buffer, k, cfg.ddpg.batch_size)
        traced = {}  # the metrics' shapes, kept by the first trace of ``run`` for ``skip``

        def run(_):
            student, explorer = state.student, state.explorer
            metrics, weights = [], []
            for start in range(0, num, block):
                n = min(block, num - start)
                k_upd, k_between, k_batch = jax.random.split(jax.random.fold_in(key, start), 3)
                if between is not None:
                    explorer = between(explorer, student, sample(k_batch), k_between)
                student, m = train_updates(self.student, student, state.normalizer, sample, k_upd, n)
                metrics.append(m)
                weights.append(n / num)
            mean = jax.tree.map(lambda *xs: sum(w * x for w, x in zip(weights, xs)), *metrics)
            traced.setdefault("metrics", jax.tree.map(lambda m: jax.ShapeDtypeStruct(m.shape, m.dtype), mean))
            return student, explorer, state.updates + num, mean

        def skip(_):  # the student's metrics (whatever it reports) are NaN for a cycle without updates
            if "metrics" not in traced:  # per_seed_cond traces ``run`` first; else trace it for the shapes alone
                jax.eval_shape(run, None)
            nan = jax.tree.map(lambda m: jnp.full(m.shape, jnp.nan, m.dtype), traced["metrics"])
            return state.student, state.explorer, state.updates, nan

        # A real conditional (per_seed_cond), not the per-seed select that vmap makes of a batched
        # predicate: the updates are skipped during warm-up, and the minibatch gathers stay inside the
        # branch, apart from the buffer write before them. Fused with that write, they made XLA copy the
        # whole replay buffer at every cycle (the modern preset's one-step cycles ran at half speed).
        student, explorer, updates, metrics = per_seed_cond(self.can_update(state), run, skip, None)
        return state.replace(student=student, explorer=explorer, updates=updates), metrics

    def acting_cycle(self, state: TrainState) -> tuple[TrainState, dict]:
        """The cycle of an explorer that only chooses actions (``metapg_jax.strategy.ActingExplorer``):
        ``steps_per_cycle`` env steps of its ``act`` (its ``episode_start`` first where an episode starts;
        uniformly random actions during the warm-up), stored, then ``run.train_steps`` student updates (its
        ``adapt`` before every ``adapt_every`` of them), and its ``metrics``."""
        explorer, run = self.explorer, self.config.run
        key, k_roll, k_train = jax.random.split(state.key, 3)
        warm = state.env_steps < run.warmup_steps
        student, normalizer = state.student, state.normalizer
        starts = type(explorer).episode_start is not ActingExplorer.episode_start  # not the default no-op

        def policy(carry, obs, first, k):
            k_reset, k_act, k_rand = jax.random.split(k, 3)
            if starts:
                # Episode starts are rare: the hook runs only on steps where some seed starts one
                # (per_seed_cond), and its result is kept only for those seeds.
                carry = per_seed_cond(first, lambda c: explorer.episode_start(self, c, student, k_reset),
                                      lambda c: c, carry)
            action, carry = explorer.act(self, carry, student, normalizer, obs, k_act)
            return jnp.where(warm, self.random_action(k_rand), action), carry, None

        env_state, carry, transitions, stats, _ = rollout(self.env, policy, state.env_state, state.explorer, k_roll,
                                                          self.config.steps_per_cycle)
        state = self.store(state.replace(env_state=env_state, explorer=carry, key=key), transitions)
        if explorer.adapt_every:
            stored = state.normalizer
            between = lambda e, s, batch, k: explorer.adapt(self, e, s, stored, batch, k)
            state, train_metrics = self.student_updates(state, k_train, run.train_steps, between, explorer.adapt_every)
        else:
            state, train_metrics = self.student_updates(state, k_train, run.train_steps)
        ret_mean, n_eps = completed_episode_mean(stats)
        return state, {**train_metrics, "train_return": ret_mean, "train_episodes": n_eps,
                       **explorer.metrics(state.explorer)}

    def cycle(self, state: TrainState) -> tuple[TrainState, dict]:
        """One cycle of the explorer (its own ``cycle``; an ``ActingExplorer``'s is ``acting_cycle``) and the NaN
        guard on the parameters the student and the explorer guard."""
        state, metrics = self.explorer.cycle(self, state)
        metrics["finite"] = all_finite([self.student.guarded_params(state.student),
                                        self.explorer.guarded_params(state.explorer)])
        return state.replace(cycles=state.cycles + 1), metrics

    # ------------------------------------------------------------------ chunks
    def evaluate(self, state: TrainState, key: jax.Array) -> tuple[jax.Array, jax.Array]:
        act = self.student.deterministic_policy(state.student.actor, state.normalizer)
        return evaluate(self.env, act, key, self.config.run.eval_episodes, self.config.episode_length)

    def train_chunk(self, state: TrainState) -> tuple[TrainState, dict]:
        """``cycles_per_chunk`` cycles in one scan, then one evaluation."""
        state, cycle_metrics = jax.lax.scan(lambda s, _: self.cycle(s), state, None,
                                            length=self.config.cycles_per_chunk)
        key, k_eval = jax.random.split(state.key)
        state = state.replace(key=key)
        eval_return, eval_length = self.evaluate(state, k_eval)
        metrics = {"env_steps": state.env_steps, "updates": state.updates,
                   "eval_return": eval_return, "eval_length": eval_length, "cycle": cycle_metrics}
        return state, metrics

    def train(self, key: jax.Array) -> tuple[TrainState, dict]:
        """The whole run as one scan over chunks (same numbers as the chunked host loop)."""
        state = self.init(key)
        return jax.lax.scan(lambda s, _: self.train_chunk(s), state, None, length=self.config.num_chunks)


def checkpoint_shapes(trainer: Trainer, keys: jax.Array):
    """``Checkpointer.restore``'s ``abstract_state`` for a run's seed-batched checkpoints: the trainer's
    state shapes, with the replay capacity of the config each checkpoint was written with (a run
    extended to a larger budget keeps checkpoints of the smaller capacity; ``replay.grow`` widens them)."""
    from metapg_jax.config import from_dict

    abstract = jax.eval_shape(vmap_seeds(trainer.init), keys)

    def shapes(meta: dict):
        capacity = from_dict(meta["config"]).buffer_capacity
        if capacity == trainer.config.buffer_capacity:
            return abstract
        obs, act = trainer.student.obs_size, trainer.student.action_size
        return abstract.replace(buffer=jax.eval_shape(jax.vmap(lambda _: replay.init(capacity, obs, act)), keys))

    return shapes
