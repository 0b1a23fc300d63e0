"""``make_train(config, env)``: the whole training run as pure, jittable functions.

Returns a ``Trainer`` with

* ``init(key) -> TrainState`` for one seed;
* ``train_chunk(state) -> (state, metrics)``: a ``lax.scan`` over
  ``cycles_per_chunk`` cycles followed by one evaluation;
* ``train(key) -> (state, metrics)``: ``init`` and a scan over all chunks, one
  program for the whole run.

Both paths give the same numbers for the same key. Seeds are a ``jax.vmap``
over keys of these functions; the host (``experiments.run``) jits the vmapped
``train_chunk`` once and calls it once per evaluation interval. Vmap with
``vmap_seeds`` (``axis_name=SEED_AXIS``): the numbers are the same with a plain
``jax.vmap``, but rare per-env events (a new parameter-noise perturbation at an
episode start) are then computed at every step (see ``any_over_seeds``).

A *cycle* is the DDPG baseline's (``rollout_steps`` noisy-actor steps stored,
then ``train_steps`` updates) or one meta-iteration of Algorithm 1
(``metapg_jax.meta``).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
from brax.envs.base import Env, State
from flax import struct

from metapg_jax import noise as noise_lib
from metapg_jax import normalizer as norm_lib
from metapg_jax import replay
from metapg_jax import visits as visits_lib
from metapg_jax.config import Config, validate
from metapg_jax.ddpg import DDPG, StudentState
from metapg_jax.evaluate import evaluate
from metapg_jax.rollout import completed_episode_mean, rollout
from metapg_jax.types import Transition


@struct.dataclass
class TrainState:
    student: StudentState
    normalizer: norm_lib.NormalizerState
    buffer: replay.ReplayState
    env_state: State                 # the exploring env (episodes continue across cycles)
    explorer: Any                    # NoiseState (ddpg) or TeacherState (meta)
    visits: visits_lib.VisitState    # bounded sample of visited states (state-visitation figure)
    key: jax.Array
    env_steps: jax.Array             # int32: stored env steps so far (the sample budget)
    updates: jax.Array               # int32: student updates so far
    cycles: jax.Array                # int32


def all_finite(state: TrainState) -> jax.Array:
    """NaN/inf guard, computed inside the program: are the student's (and teacher's) parameters finite?

    Returned per cycle in the metrics, so the host learns of a bad seed at the
    next chunk boundary without any host sync inside the chunk.
    """
    trees = [state.student.actor, state.student.critic]
    if hasattr(state.explorer, "params"):
        trees.append(state.explorer.params)
    return jnp.all(jnp.stack([jnp.all(jnp.isfinite(x)) for x in jax.tree.leaves(trees)]))


SEED_AXIS = "seeds"


def vmap_seeds(fn, **kwargs):
    """``jax.vmap`` over the seed axis, named ``SEED_AXIS`` (see ``any_over_seeds``)."""
    return jax.vmap(fn, axis_name=SEED_AXIS, **kwargs)


def any_over_seeds(flag: jax.Array) -> jax.Array:
    """Whether ``flag`` holds for any seed of the batch: an unbatched predicate for ``lax.cond``.

    Under ``vmap`` a ``lax.cond`` on a per-seed predicate becomes a ``select`` that computes both
    branches for every seed at every call. ``lax.cond(any_over_seeds(p), lambda: where(p, a(), b),
    lambda: b)`` gives the same values and runs ``a`` only when some seed needs it. Outside a
    ``vmap_seeds`` (one seed, or a plain ``jax.vmap``) the axis is unbound and ``flag`` is returned.
    """
    try:
        return jax.lax.pmax(flag.astype(jnp.int32), SEED_AXIS) > 0
    except NameError:  # no vmap named SEED_AXIS around this trace
        return flag


def seed_keys(seed: int, num_seeds: int) -> jax.Array:
    """One key per seed; seed i's key does not depend on how many seeds run."""
    base = jax.random.PRNGKey(seed)
    return jnp.stack([jax.random.fold_in(base, i) for i in range(num_seeds)])


def flatten_time(tree):
    """Merges the two leading axes (e.g. time x envs) of every leaf."""
    return jax.tree.map(lambda x: x.reshape((-1,) + x.shape[2:]), tree)


def train_updates(ddpg: DDPG, student: StudentState, normalizer, sample, key: jax.Array, num: int):
    """``num`` DDPG updates with minibatches from ``sample(key)``; returns the mean metrics."""

    def step(st, k):
        return ddpg.update(st, normalizer, sample(k))

    student, metrics = jax.lax.scan(step, student, jax.random.split(key, num))
    return student, jax.tree.map(jnp.mean, metrics)


@dataclasses.dataclass(frozen=True)
class Trainer:
    config: Config
    env: Env
    ddpg: DDPG

    # ------------------------------------------------------------------ init
    def init(self, key: jax.Array) -> TrainState:
        cfg = self.config
        k_student, k_env, k_explorer, key = jax.random.split(key, 4)
        student = self.ddpg.init(k_student)
        env_state = self.env.reset(k_env)
        state = TrainState(
            student=student,
            normalizer=norm_lib.init(self.ddpg.obs_size),
            buffer=replay.init(cfg.buffer_capacity, self.ddpg.obs_size, self.ddpg.action_size),
            env_state=env_state,
            explorer=None,
            visits=visits_lib.init(cfg.meta.visit_samples, self.ddpg.obs_size),
            key=key,
            env_steps=jnp.zeros((), jnp.int32),
            updates=jnp.zeros((), jnp.int32),
            cycles=jnp.zeros((), jnp.int32),
        )
        if cfg.run.method == "meta":
            from metapg_jax import meta

            return meta.init_state(self, state, k_explorer)
        return state.replace(explorer=noise_lib.init(cfg.noise, student.actor, self.ddpg.action_size))

    # ------------------------------------------------------------------ cycles
    def store(self, state: TrainState, transitions: Transition) -> TrainState:
        """Adds a flat batch of transitions to the buffer and the normaliser; counts them."""
        n = transitions.reward.shape[0]
        return state.replace(
            buffer=replay.add(state.buffer, transitions),
            normalizer=norm_lib.update(state.normalizer, transitions.obs),
            env_steps=state.env_steps + n,
        )

    def can_update(self, state: TrainState) -> jax.Array:
        """Updates start once the warm-up is over and the buffer holds a minibatch."""
        return jnp.logical_and(state.env_steps >= self.config.run.warmup_steps,
                               state.buffer.size >= self.config.ddpg.batch_size)

    def random_action(self, key: jax.Array) -> jax.Array:
        return jax.random.uniform(key, (self.ddpg.action_size,), jnp.float32, -1.0, 1.0)

    def ddpg_cycle(self, state: TrainState) -> tuple[TrainState, dict]:
        """The baseline's cycle: ``rollout_steps`` noisy-actor steps, then ``train_steps`` updates."""
        cfg, ddpg = self.config, self.ddpg
        key, k_roll, k_train = jax.random.split(state.key, 3)
        warm = state.env_steps < cfg.run.warmup_steps
        actor, normalizer = state.student.actor, state.normalizer

        def policy(carry, obs, first, k):
            k_reset, k_act, k_rand = jax.random.split(k, 3)
            # Episode starts are rare: the new perturbation (adaptive-param) is drawn only on steps
            # where some seed starts an episode (any_over_seeds), and kept only for those seeds.
            carry = jax.lax.cond(
                any_over_seeds(first),
                lambda: jax.tree.map(lambda new, old: jnp.where(first, new, old),
                                     noise_lib.episode_start(cfg.noise, carry, actor, k_reset), carry),
                lambda: carry)
            action, carry = noise_lib.act(cfg.noise, carry, ddpg.actor_apply, actor,
                                          ddpg.normalize(normalizer, obs), k_act)
            return jnp.where(warm, self.random_action(k_rand), action), carry, None

        env_state, explorer, transitions, stats, _ = rollout(
            self.env, policy, state.env_state, state.explorer, k_roll, cfg.run.rollout_steps)
        state = self.store(state.replace(env_state=env_state, explorer=explorer, key=key,
                                         visits=visits_lib.record(state.visits, explore_obs=transitions.obs)),
                           transitions)

        state, train_metrics = self.student_updates(state, k_train, cfg.run.train_steps)
        ret_mean, n_eps = completed_episode_mean(stats)
        metrics = {**train_metrics, "train_return": ret_mean, "train_episodes": n_eps,
                   "param_noise_stddev": state.explorer.stddev, "param_noise_distance": state.explorer.distance}
        return state, metrics

    def student_updates(self, state: TrainState, key: jax.Array, num: int):
        """``num`` updates of the student on replay minibatches (skipped during warm-up).

        With adaptive parameter noise, the noise stddev is adapted before updates
        0, adapt_every, 2 adapt_every, ... of the block, as baselines does within
        each cycle (``t_train % param_noise_adaption_interval == 0``). The
        positions are static, so no per-update conditional is needed.
        """
        ddpg, cfg = self.ddpg, self.config
        adaptive = cfg.run.method == "ddpg" and cfg.noise.kind == "adaptive-param"
        block = cfg.noise.adapt_every if adaptive else num
        sample = lambda k: replay.sample(state.buffer, k, cfg.ddpg.batch_size)

        def run(_):
            student, explorer = state.student, state.explorer
            metrics, weights = [], []
            for start in range(0, num, block):
                n = min(block, num - start)
                k_upd, k_adapt, k_batch = jax.random.split(jax.random.fold_in(key, start), 3)
                if adaptive:
                    obs = ddpg.normalize(state.normalizer, sample(k_batch).obs)
                    explorer = noise_lib.adapt(cfg.noise, explorer, ddpg.actor_apply, student.actor, obs, k_adapt)
                student, m = train_updates(ddpg, student, state.normalizer, sample, k_upd, n)
                metrics.append(m)
                weights.append(n / num)
            mean = jax.tree.map(lambda *xs: sum(w * x for w, x in zip(weights, xs)), *metrics)
            return student, explorer, state.updates + num, mean

        def skip(_):
            nan = jnp.full((), jnp.nan, jnp.float32)
            return state.student, state.explorer, state.updates, {
                "critic_loss": nan, "actor_loss": nan, "q_mean": nan, "td_loss": nan}

        # A real conditional (any_over_seeds), not the per-seed select that vmap makes of a batched
        # predicate: the updates are skipped during warm-up, and the minibatch gathers stay inside the
        # branch, apart from the buffer write before them. Fused with that write, they made XLA copy the
        # whole replay buffer at every cycle (the modern preset's one-step cycles ran at half speed).
        ok = self.can_update(state)
        student, explorer, updates, metrics = jax.lax.cond(
            any_over_seeds(ok),
            lambda _: jax.tree.map(lambda a, b: jnp.where(ok, a, b), run(None), skip(None)), skip, None)
        return state.replace(student=student, explorer=explorer, updates=updates), metrics

    def cycle(self, state: TrainState) -> tuple[TrainState, dict]:
        if self.config.run.method == "meta":
            from metapg_jax import meta

            state, metrics = meta.meta_cycle(self, state)
        else:
            state, metrics = self.ddpg_cycle(state)
        metrics["finite"] = all_finite(state)
        return state.replace(cycles=state.cycles + 1), metrics

    # ------------------------------------------------------------------ chunks
    def evaluate(self, state: TrainState, key: jax.Array) -> tuple[jax.Array, jax.Array]:
        act = self.ddpg.deterministic_policy(state.student.actor, state.normalizer)
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
        obs, act = trainer.ddpg.obs_size, trainer.ddpg.action_size
        return abstract.replace(buffer=jax.eval_shape(jax.vmap(lambda _: replay.init(capacity, obs, act)), keys))

    return shapes


def make_train(config: Config, env: Env | None = None) -> Trainer:
    """Validates ``config`` and builds the trainer (``env`` defaults to ``envs.make`` of the config)."""
    import envs

    validate(config)
    if env is None:
        env = envs.make(config.env.name, source=config.env.source, episode_length=config.episode_length,
                        physics=config.env.physics)
    ddpg = DDPG(config.ddpg, int(env.observation_size), int(env.action_size))
    return Trainer(config, env, ddpg)
