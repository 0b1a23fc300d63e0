"""Algorithm 1 of Xu et al. (2018), one meta-iteration ("cycle") as the scan body.

Per seed, per cycle (../shared/DESIGN.md steps 1-8; defaults in brackets):

1. D0: ``explore_steps`` [100] transitions from the teacher pi_e in the
   exploring env (episodes continue across cycles).
2. pi' = DDPG(pi, D0): ``lookahead_steps`` [= train_steps, 50] updates of a
   *copy* of the student on minibatches drawn from D0 only
   (``lookahead_data='d0'``; 'mix', ours: from the replay buffer and D0).
3. D1: the deterministic pi' from fresh resets for ``eval_steps`` [200] steps
   in ``eval_envs`` [1] envs (auto-resetting). R_hat(pi') = mean over envs of
   the return of the *first* episode, truncated at ``eval_steps``.
4. Meta reward R(D0) = R_hat(pi') - R_hat(pi), R_hat(pi) carried from the
   previous cycle. Before the first estimate exists it is 0 (see deviations).
   With ``baseline='paired'`` (ours) R_hat(pi) is a rollout of the student pi
   itself from the same resets as D1's (stored and counted like D1), so the
   difference is the look-ahead's gain on the same start states, from the
   first cycle on. With ``baseline='counterfactual'`` (ours) R_hat(pi) is
   R_hat(pi''), a second look-ahead copy trained as long without D0, rolled
   out from the same resets (``metapg_jax/counterfactual.py``).
5. Teacher: ``teacher_steps`` [1] Adam steps of REINFORCE (eq. 5) on D0.
6. Buffer <- D0, D1 (and the normaliser sees their observations).
7. Student: ``train_steps`` [50] DDPG updates on the buffer, starting from pi
   (``student_from='pi'``, the paper) or from pi' (``'lookahead'``).
8. R_hat(pi) for the next cycle: R_hat(pi') (``baseline='lookahead'``, no
   extra samples) or a fresh rollout D2 of the updated student
   (``baseline='fresh'``; D2 is stored and counted like D1); nothing with
   ``baseline='paired'`` or ``'counterfactual'``.

The teacher is the design ``meta.teacher`` names (``metapg_jax.teacher``: the paper's two, and one file each in
this package for the others). With ``baseline='paired'`` and two or more eval envs the cycle also measures the
meta reward's noise (``meta_reward_spread``): the spread over the envs of the per-env differences of the paired
rollouts, and what it would be unpaired.

Deviations from the paper's Algorithm 1 (also in docs/algorithm.md):
* Lines 2-3 (an initial D1 from pi to estimate R_hat(pi) and seed the buffer)
  are folded into the first cycle: the buffer starts empty and the first
  cycle's meta reward is 0, so every stored step belongs to a cycle and
  DDPG and Meta runs of the same budget see the same number of samples.
* With ``baseline='lookahead'`` R_hat(pi) is the previous cycle's R_hat(pi'),
  not a new estimate of the updated student (the paper says "compute the new
  R_hat(pi)" without saying how; a fresh estimate costs samples).

Our readings where the paper gives no number or procedure (also in docs/algorithm.md):
* The look-ahead runs ``train_steps`` updates (50; 500 where the paper's cycle
  for the task is longer), the paper's "one or a small number of steps" read as
  the student's own count.
* R_hat(pi') is one first-episode return per eval env, truncated at
  ``eval_steps``: on the 1000-step tasks a 200-step partial return (2000 steps,
  i.e. whole episodes, where the paper's cycle for the task is longer).
* The teacher's env is not reset between cycles: D0 continues its episodes.

``TeacherExplorer`` is this cycle as an explorer, registered as ``meta`` (``--method=meta``; its group is
``meta``, its shortcut ``--teacher``): the teacher explores, and what it does with its data is the
look-ahead, the meta reward and the REINFORCE step. This file also reads the paper's schedule for the task (its
spec's ``meta_schedule``, envs) and holds what each preset changes for the teacher.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import jax
import jax.numpy as jnp

import envs
from metapg_jax import strategy
from metapg_jax import teacher as teacher_lib
from metapg_jax.config import positive
from metapg_jax.loop import TrainState, Trainer, flatten_time, train_updates
from metapg_jax.rollout import completed_episode_mean, rollout
from metapg_jax import counterfactual
from metapg_jax.teacher import Teacher, TeacherState


@dataclasses.dataclass(frozen=True)
class MetaConfig:
    """The teacher and Algorithm 1's schedule (../shared/DESIGN.md, paper section 4 and 5.1)."""

    # 'independent' (own mean + log-std MLPs), 'variance' (student mean), or another registered design
    # (metapg_jax.teacher.designs())
    teacher: str = "independent"
    hidden: tuple[int, ...] = (64, 64)
    layer_norm: bool = True         # the paper uses LayerNorm in its policy networks
    # Variance teacher: log-std MLP (True, our default, like the log-std network of the paper's
    # section 5.1) or one learned vector (False, the paper's design (i), sigma^2 I).
    state_dependent_std: bool = True
    init_log_std: float = -0.5      # initial log-std of the teacher (ours; the paper does not say)
    min_log_std: float = -5.0       # log-std bounds (ours)
    max_log_std: float = 1.0
    lr: float = 1e-4                # teacher Adam learning rate (paper); 0 = frozen at its init (a control)
    explore_steps: int = 100        # |D0| per cycle
    eval_steps: int = 200           # |D1| per cycle, per eval env
    teacher_steps: int = 1          # REINFORCE Adam steps per cycle
    # DDPG updates of the look-ahead copy on D0; 0 = run.train_steps (50; 500 in the paper's longer cycle).
    # The paper says "one or a small number of steps" without a number; ours is a reading.
    lookahead_steps: int = 0
    eval_envs: int = 1              # parallel envs for D1
    student_from: str = "pi"        # student update starts from pi (paper) or pi'
    # R_hat(pi): the previous cycle's R_hat(pi') ('lookahead'), a fresh rollout of the updated student ('fresh'),
    # a rollout of this cycle's student from D1's resets ('paired', ours), or of a look-ahead copy trained as long
    # without D0 ('counterfactual', ours; metapg_jax/counterfactual.py)
    baseline: str = "lookahead"
    # The look-ahead's minibatches: from D0 alone ('d0', the paper) or from the replay buffer and D0 ('mix', ours)
    lookahead_data: str = "d0"
    normalize_meta_reward: bool = False  # running mean/std of the meta reward (our addition)


# Algorithm 1's schedule (section 5.1, "typically"): |D0|, |D1|, student updates per cycle, REINFORCE steps per
# cycle; a task whose spec has a ``meta_schedule`` (envs.TaskSpec: the paper's own cycle for it) runs that.
_DEFAULT_SCHEDULE = dict(explore_steps=100, eval_steps=200, train_steps=50, teacher_steps=1)


def paper_schedule(task: str) -> dict[str, int]:
    """The paper's schedule on ``task``: its spec's ``meta_schedule``, else ``_DEFAULT_SCHEDULE``."""
    schedule = envs.get_spec(task).meta_schedule
    return _DEFAULT_SCHEDULE if schedule is None else dataclasses.asdict(schedule)


def make_teacher(trainer: Trainer) -> Teacher:
    """The design ``meta.teacher`` names (``metapg_jax.teacher.make``)."""
    return teacher_lib.make(trainer.config, trainer.student)


@dataclasses.dataclass(frozen=True)
class TeacherExplorer(strategy.Explorer):
    """Algorithm 1's teacher as the explorer: ``init`` builds the teacher, ``cycle`` is ``meta_cycle``; the NaN
    guard checks the teacher's parameters."""

    cfg: MetaConfig

    def init(self, trainer: Trainer, student, key: jax.Array) -> TeacherState:
        return make_teacher(trainer).init(key)

    def cycle(self, trainer: Trainer, state: TrainState) -> tuple[TrainState, dict]:
        return meta_cycle(trainer, state)

    def guarded_params(self, carry: TeacherState):
        return carry.params


def first_episode_return(rewards: jax.Array, dones: jax.Array) -> jax.Array:
    """Return of the first episode of a (T,) rollout, truncated at T.

    Step t counts if no episode ended before it (the ending step itself counts).
    """
    ended_before = jnp.cumsum(dones) - dones
    return jnp.sum(jnp.where(ended_before > 0, 0.0, rewards))


def student_rollout(trainer: Trainer, actor, normalizer, key: jax.Array):
    """D1 (or D2): the deterministic student from fresh resets in ``eval_envs`` envs; the same ``key`` gives the
    same resets (the paired baseline's rollout of pi starts where D1's of pi' did).

    Returns (flat transitions (eval_envs * eval_steps), each env's first-episode return (eval_envs,)); R_hat is
    their mean.
    """
    cfg = trainer.config.meta
    act = trainer.student.deterministic_policy(actor, normalizer)
    policy = lambda carry, obs, first, k: (act(obs), carry, None)
    k_reset, k_roll = jax.random.split(key)
    env_states = jax.vmap(trainer.env.reset)(jax.random.split(k_reset, cfg.eval_envs))

    def one_env(env_state, k):
        _, _, tr, stats, _ = rollout(trainer.env, policy, env_state, None, k, cfg.eval_steps)
        return tr, first_episode_return(tr.reward, stats.done)

    transitions, returns = jax.vmap(one_env)(env_states, jax.random.split(k_roll, cfg.eval_envs))
    # (envs, T, ...) -> (envs * T, ...)
    return flatten_time(transitions), returns


# ``fold_in`` data for the teacher's ``begin_cycle`` key, derived from D0's key: an index that D0's rollout, which
# splits that key into ``explore_steps`` keys, never reaches (``fold_in(k, i)`` may equal ``split(k, n)[i]``), so no
# key is used twice and the cycle's six keys (and every earlier design's numbers) stay as they were.
BEGIN_CYCLE_KEY = 2 ** 31 - 1


def _sd(x: jax.Array) -> jax.Array:
    """Sample standard deviation (ddof 1) over the last axis; NaN for fewer than two values."""
    n = x.shape[-1]
    return jnp.sqrt(jnp.sum(jnp.square(x - jnp.mean(x, -1, keepdims=True)), -1) / (n - 1)) if n > 1 else jnp.nan


def meta_reward_spread(returns_lookahead: jax.Array, returns_pi: jax.Array) -> dict:
    """The paired meta reward's noise from one cycle's per-env returns of pi' and of pi from the same resets:
    the spread (sample std) of the per-env differences, and that of a difference of independent rollouts,
    sqrt(sd(R(pi'))^2 + sd(R(pi))^2) (NaN for one env)."""
    return {"meta_reward_sd_paired": _sd(returns_lookahead - returns_pi),
            "meta_reward_sd_unpaired": jnp.sqrt(jnp.square(_sd(returns_lookahead)) + jnp.square(_sd(returns_pi)))}


def meta_cycle(trainer: Trainer, state: TrainState) -> tuple[TrainState, dict]:
    """One meta-iteration of Algorithm 1 (module docstring)."""
    cfg, learner = trainer.config, trainer.student
    m = cfg.meta
    teacher = make_teacher(trainer)
    tstate: TeacherState = state.explorer
    key, k_d0, k_look, k_d1, k_train, k_d2 = jax.random.split(state.key, 6)
    tstate = teacher.begin_cycle(tstate, jax.random.fold_in(k_d0, BEGIN_CYCLE_KEY))
    student, normalizer = state.student, state.normalizer
    norm = lambda obs: learner.normalize(normalizer, obs)

    # 1. D0 from the teacher (clipped action to the env; the unclipped sample kept for log pi_e).
    def teacher_policy(carry, obs, first, k):
        action, raw, carry = teacher.sample_step(tstate.params, carry, student.actor, norm(obs), first, k)
        return action, carry, raw

    env_state, d0_carry, d0, d0_stats, d0_raw = rollout(trainer.env, teacher_policy, state.env_state,
                                                        teacher.d0_carry(tstate), k_d0, m.explore_steps)
    tstate = teacher.end_d0(tstate, d0_carry)

    # 2. Look-ahead: a copy of the student trained on D0 (and the buffer: 'mix'). `student` itself is not changed.
    n_look = m.lookahead_steps or cfg.run.train_steps
    sample_look = counterfactual.lookahead_sampler(m.lookahead_data, state.buffer, d0, cfg.ddpg.batch_size)
    lookahead, look_metrics = train_updates(learner, student, normalizer, sample_look, k_look, n_look)

    # 3. D1 from pi' and R_hat(pi').
    d1, returns_lookahead = student_rollout(trainer, lookahead.actor, normalizer, k_d1)
    r_hat_lookahead = jnp.mean(returns_lookahead)

    # 4. Meta reward (0 until R_hat(pi) exists). Paired: R_hat(pi) now, from D1's resets; counterfactual: R_hat(pi'')
    # from them, pi'' the look-ahead without D0 (the same keys), once the buffer holds a minibatch.
    if m.baseline in ("paired", "counterfactual"):
        baseline, ready = student, True
        if m.baseline == "counterfactual":
            baseline, ready = counterfactual.without_d0(learner, student, normalizer, state.buffer,
                                                        cfg.ddpg.batch_size, k_look, n_look)
        d_pi, returns_pi = student_rollout(trainer, baseline.actor, normalizer, k_d1)
        tstate = tstate.replace(r_hat=jnp.where(ready, jnp.mean(returns_pi), jnp.nan))
        noise = meta_reward_spread(returns_lookahead, returns_pi)
    else:
        noise = {"meta_reward_sd_paired": jnp.nan, "meta_reward_sd_unpaired": jnp.nan}
    have_baseline = jnp.isfinite(tstate.r_hat)
    meta_reward = jnp.where(have_baseline, r_hat_lookahead - tstate.r_hat, 0.0)
    signal = meta_reward
    if m.normalize_meta_reward:
        tstate_n, normalized = teacher.normalize_reward(tstate, meta_reward)
        tstate = jax.tree.map(lambda new, old: jnp.where(have_baseline, new, old), tstate_n, tstate)
        signal = jnp.where(have_baseline, normalized, 0.0)

    # 5. Teacher update by REINFORCE on D0.
    d0_obs_n = norm(d0.obs)
    params_d0 = tstate.params  # the teacher that produced D0, for the diagnostics below
    tstate = teacher.update(tstate, student.actor, d0_obs_n, d0_raw, signal)

    # 6. Buffer <- D0, D1 (the teacher's states and the student's, in the visitation sample).
    state = trainer.store(state.replace(env_state=env_state, key=key), d0)
    state = trainer.store(state, d1, source="student")
    if m.baseline in ("paired", "counterfactual"):
        state = trainer.store(state, d_pi, source="student")

    # 7. Student update on the buffer, from pi (paper) or from pi'.
    if m.student_from == "lookahead":
        state = state.replace(student=lookahead)
    state, train_metrics = trainer.student_updates(state, k_train, cfg.run.train_steps)

    # 8. R_hat(pi) for the next cycle.
    r_hat_pi = tstate.r_hat
    if m.baseline == "fresh":
        d2, returns_next = student_rollout(trainer, state.student.actor, state.normalizer, k_d2)
        r_hat_next = jnp.mean(returns_next)
        state = trainer.store(state, d2, source="student")
    else:
        r_hat_next = r_hat_lookahead
    state = state.replace(explorer=tstate.replace(r_hat=r_hat_next))

    # Teacher diagnostics on D0 (with the teacher before its update, which produced D0).
    student_action = learner.actor_apply(student.actor, d0_obs_n)
    ret_mean, n_eps = completed_episode_mean(d0_stats)
    metrics = {
        **train_metrics,
        "lookahead_critic_loss": look_metrics["critic_loss"],
        "train_return": ret_mean, "train_episodes": n_eps,
        "meta_reward": meta_reward,
        "r_hat_pi": r_hat_pi,
        "r_hat_lookahead": r_hat_lookahead,
        **teacher.diagnostics(params_d0, student.actor, d0_obs_n),
        "teacher_student_distance": jnp.sqrt(jnp.mean(jnp.square(d0.action - student_action))),
        **noise,
    }
    return state, metrics


# ---------------------------------------------------------------------------------------------- the strategy
NAME = "meta"
STUDENT_FROM = ("pi", "lookahead")
BASELINES = ("lookahead", "fresh", "paired", "counterfactual")
# The tuned preset's changes to the paper preset's Meta schedule, each from a screen cell at 300k steps
# (results/screen/README.md); applied after the overrides, a field that --set names is left as set.
TUNED_META = {
    "run.train_steps": "half the cycle's stored steps (DDPG's 50 updates per 100 stored steps)",
    "meta.lookahead_steps": "the paper preset's student updates per cycle (50; 500 in the paper's longer cycle)",
    "meta.teacher_steps": "1 (the paper preset: 100 in the paper's longer cycle)",
}


def _group_defaults(config) -> MetaConfig:
    """The task's paper schedule; under the modern preset a 256-256 teacher without LayerNorm."""
    s = paper_schedule(config.env.name)
    meta = MetaConfig(explore_steps=s["explore_steps"], eval_steps=s["eval_steps"], teacher_steps=s["teacher_steps"])
    if config.preset == "modern":
        meta = dataclasses.replace(meta, hidden=(256, 256), layer_norm=False)
    return meta


def _schedule(config):
    """Chosen as the explorer: the task's student updates per cycle under the paper and tuned presets (a 3000-step
    cycle has 500 where the paper says so; the DDPG baseline keeps baselines' 50 per 100-step cycle); no random
    warm-up under the modern preset (the teacher is the exploration from the first step)."""
    run = config.run
    if config.preset in ("paper", "tuned"):
        run = dataclasses.replace(run, train_steps=paper_schedule(config.env.name)["train_steps"])
    else:
        run = dataclasses.replace(run, warmup_steps=0)
    return config.replace(run=run)


def _derive(config, overrides: dict[str, Any]):
    """After --set: under the modern preset one student update per stored step and one look-ahead update per D0
    step; under the tuned preset ``TUNED_META``. A field that --set names keeps its value."""
    run, meta = config.run, config.meta
    if config.preset == "modern":
        if "run.train_steps" not in overrides:
            run = dataclasses.replace(run, train_steps=steps_per_cycle(config))
        if "meta.lookahead_steps" not in overrides:
            meta = dataclasses.replace(meta, lookahead_steps=meta.explore_steps)
    if config.preset == "tuned":
        if "meta.lookahead_steps" not in overrides:
            meta = dataclasses.replace(meta, lookahead_steps=meta.lookahead_steps or run.train_steps)
        if "meta.teacher_steps" not in overrides:
            meta = dataclasses.replace(meta, teacher_steps=1)
        if "run.train_steps" not in overrides:
            run = dataclasses.replace(run, train_steps=max(1, steps_per_cycle(config) // 2))
    return config.replace(run=run, meta=meta)


def steps_per_cycle(config) -> int:
    """D0, D1 in every eval env, and D2 (``baseline='fresh'``), the rollout of pi (``'paired'``) or of pi''
    (``'counterfactual'``): every step a cycle stores."""
    m = config.meta
    fresh = m.eval_steps * m.eval_envs if m.baseline in ("fresh", "paired", "counterfactual") else 0
    return m.explore_steps + m.eval_steps * m.eval_envs + fresh


def _validate(config) -> None:
    m = config.meta
    if m.teacher not in teacher_lib.designs():
        raise ValueError(f"unknown teacher {m.teacher!r}; valid teachers: {', '.join(teacher_lib.designs())}")
    if m.student_from not in STUDENT_FROM:
        raise ValueError(f"meta.student_from must be one of {', '.join(STUDENT_FROM)}, got {m.student_from!r}")
    if m.baseline not in BASELINES:
        raise ValueError(f"meta.baseline must be one of {', '.join(BASELINES)}, got {m.baseline!r}")
    if m.lookahead_data not in counterfactual.LOOKAHEAD_DATA:
        raise ValueError(f"meta.lookahead_data must be one of {', '.join(counterfactual.LOOKAHEAD_DATA)}, "
                         f"got {m.lookahead_data!r}")
    if m.lookahead_steps < 0:
        raise ValueError("meta.lookahead_steps must be >= 0")
    if config.run.method != NAME:
        return
    for name in ("explore_steps", "eval_steps", "teacher_steps", "eval_envs"):
        positive(f"meta.{name}", getattr(m, name))
    # meta.lr = 0 freezes the teacher at its initialisation (a control: the data without the learning).
    if not (math.isfinite(m.lr) and m.lr >= 0):
        raise ValueError(f"meta.lr must be a finite number >= 0 (0 = a frozen teacher), got {m.lr!r}")
    if not m.hidden or min(m.hidden) <= 0:
        raise ValueError(f"meta.hidden must be a non-empty tuple of positive widths, got {m.hidden}")
    if not m.min_log_std < m.init_log_std < m.max_log_std:
        raise ValueError("meta log-std bounds must satisfy min_log_std < init_log_std < max_log_std")


CYCLE_METRICS = ("meta_reward", "r_hat_pi", "r_hat_lookahead", "teacher_log_std", "teacher_entropy",
                 "teacher_student_distance", "teacher_mean_distance", "meta_reward_sd_paired",
                 "meta_reward_sd_unpaired")

strategy.register_explorer(
    NAME, lambda config: TeacherExplorer(config.meta), group=MetaConfig, group_defaults=_group_defaults,
    schedule=_schedule, derive=_derive, validate=_validate, steps_per_cycle=steps_per_cycle,
    cycle_metrics=CYCLE_METRICS,
    cycle_panels=(("meta_reward", "meta reward R_hat(pi') - R_hat(pi)"), ("teacher_log_std", "teacher mean log-std"),
                  (("r_hat_lookahead", "r_hat_pi"), "R_hat(pi') and R_hat(pi)"),
                  ("teacher_student_distance", "RMS teacher - student action on D0")),
    plot_file="teacher.png", label=lambda config: config.meta.teacher, flag=("teacher", "teacher"),
    moved={"visit_samples": "run.visit_samples"},
    summary="the paper's learned teacher (Algorithm 1; --teacher)")
