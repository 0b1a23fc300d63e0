"""Algorithm 1 of Xu et al. (2018), one meta-iteration ("cycle") as the scan body.

Per seed, per cycle (../shared/DESIGN.md steps 1-8; defaults in brackets):

1. D0: ``explore_steps`` [100] transitions from the teacher pi_e in the
   exploring env (episodes continue across cycles).
2. pi' = DDPG(pi, D0): ``lookahead_steps`` [= train_steps, 50] updates of a
   *copy* of the student on minibatches drawn from D0 only.
3. D1: the deterministic pi' from fresh resets for ``eval_steps`` [200] steps
   in ``eval_envs`` [1] envs (auto-resetting). R_hat(pi') = mean over envs of
   the return of the *first* episode, truncated at ``eval_steps``.
4. Meta reward R(D0) = R_hat(pi') - R_hat(pi), R_hat(pi) carried from the
   previous cycle. Before the first estimate exists it is 0 (see deviations).
5. Teacher: ``teacher_steps`` [1] Adam steps of REINFORCE (eq. 5) on D0.
6. Buffer <- D0, D1 (and the normaliser sees their observations).
7. Student: ``train_steps`` [50] DDPG updates on the buffer, starting from pi
   (``student_from='pi'``, the paper) or from pi' (``'lookahead'``).
8. R_hat(pi) for the next cycle: R_hat(pi') (``baseline='lookahead'``, no
   extra samples) or a fresh rollout D2 of the updated student
   (``baseline='fresh'``; D2 is stored and counted like D1).

Deviations from the paper's Algorithm 1 (also in docs/algorithm.md):
* Lines 2-3 (an initial D1 from pi to estimate R_hat(pi) and seed the buffer)
  are folded into the first cycle: the buffer starts empty and the first
  cycle's meta reward is 0, so every stored step belongs to a cycle and
  DDPG and Meta runs of the same budget see the same number of samples.
* With ``baseline='lookahead'`` R_hat(pi) is the previous cycle's R_hat(pi'),
  not a new estimate of the updated student (the paper says "compute the new
  R_hat(pi)" without saying how; a fresh estimate costs samples).

Our readings where the paper gives no number or procedure (also in docs/algorithm.md):
* The look-ahead runs ``train_steps`` updates (50; 500 on IP/HalfCheetah), the
  paper's "one or a small number of steps" read as the student's own count.
* R_hat(pi') is one first-episode return per eval env, truncated at
  ``eval_steps``: on the 1000-step tasks a 200-step partial return (2000 steps
  on IP/HalfCheetah, i.e. whole episodes).
* The teacher's env is not reset between cycles: D0 continues its episodes.

``TeacherExplorer`` is this cycle as an explorer (``metapg_jax.explorers``): the teacher explores, and
what it does with its data is the look-ahead, the meta reward and the REINFORCE step.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp

from metapg_jax import visits as visits_lib
from metapg_jax.config import MetaConfig
from metapg_jax.loop import TrainState, Trainer, flatten_time, train_updates
from metapg_jax.rollout import completed_episode_mean, rollout
from metapg_jax.teacher import Teacher, TeacherState


def make_teacher(trainer: Trainer) -> Teacher:
    return Teacher(trainer.config.meta, trainer.student)


@dataclasses.dataclass(frozen=True)
class TeacherExplorer:
    """Algorithm 1's teacher as the explorer: ``init`` builds the teacher, ``cycle`` is ``meta_cycle``."""

    cfg: MetaConfig

    def init(self, trainer: Trainer, student, key: jax.Array) -> TeacherState:
        return make_teacher(trainer).init(key)

    def cycle(self, trainer: Trainer, state: TrainState) -> tuple[TrainState, dict]:
        return meta_cycle(trainer, state)


def first_episode_return(rewards: jax.Array, dones: jax.Array) -> jax.Array:
    """Return of the first episode of a (T,) rollout, truncated at T.

    Step t counts if no episode ended before it (the ending step itself counts).
    """
    ended_before = jnp.cumsum(dones) - dones
    return jnp.sum(jnp.where(ended_before > 0, 0.0, rewards))


def student_rollout(trainer: Trainer, actor, normalizer, key: jax.Array):
    """D1 (or D2): the deterministic student from fresh resets in ``eval_envs`` envs.

    Returns (flat transitions (eval_envs * eval_steps), R_hat = mean first-episode return).
    """
    cfg = trainer.config.meta
    act = trainer.student.deterministic_policy(actor, normalizer)
    policy = lambda carry, obs, first, k: (act(obs), carry, None)
    k_reset, k_roll = jax.random.split(key)
    env_states = jax.vmap(trainer.env.reset)(jax.random.split(k_reset, cfg.eval_envs))

    def one_env(env_state, k):
        _, _, tr, stats, _ = rollout(trainer.env, policy, env_state, None, k, cfg.eval_steps)
        return tr, first_episode_return(tr.reward, stats.done)

    transitions, r_hat = jax.vmap(one_env)(env_states, jax.random.split(k_roll, cfg.eval_envs))
    # (envs, T, ...) -> (envs * T, ...)
    return flatten_time(transitions), jnp.mean(r_hat)


def meta_cycle(trainer: Trainer, state: TrainState) -> tuple[TrainState, dict]:
    """One meta-iteration of Algorithm 1 (module docstring)."""
    cfg, learner = trainer.config, trainer.student
    m = cfg.meta
    teacher = make_teacher(trainer)
    tstate: TeacherState = state.explorer
    key, k_d0, k_look, k_d1, k_train, k_d2 = jax.random.split(state.key, 6)
    student, normalizer = state.student, state.normalizer
    norm = lambda obs: learner.normalize(normalizer, obs)

    # 1. D0 from the teacher (clipped action to the env; the unclipped sample kept for log pi_e).
    def teacher_policy(carry, obs, first, k):
        action, raw = teacher.sample(tstate.params, student.actor, norm(obs), k)
        return action, carry, raw

    env_state, _, d0, d0_stats, d0_raw = rollout(trainer.env, teacher_policy, state.env_state, None, k_d0,
                                                 m.explore_steps)

    # 2. Look-ahead: a copy of the student trained on D0 only. `student` itself is not changed.
    def sample_d0(k):
        idx = jax.random.randint(k, (cfg.ddpg.batch_size,), 0, m.explore_steps)
        return jax.tree.map(lambda x: x[idx], d0)

    lookahead, look_metrics = train_updates(learner, student, normalizer, sample_d0, k_look,
                                            m.lookahead_steps or cfg.run.train_steps)

    # 3. D1 from pi' and R_hat(pi').
    d1, r_hat_lookahead = student_rollout(trainer, lookahead.actor, normalizer, k_d1)

    # 4. Meta reward (0 until R_hat(pi) exists).
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

    # 6. Buffer <- D0, D1.
    state = trainer.store(state.replace(env_state=env_state, key=key), d0)
    state = trainer.store(state, d1)

    # 7. Student update on the buffer, from pi (paper) or from pi'.
    if m.student_from == "lookahead":
        state = state.replace(student=lookahead)
    state, train_metrics = trainer.student_updates(state, k_train, cfg.run.train_steps)

    # 8. R_hat(pi) for the next cycle.
    r_hat_pi = tstate.r_hat
    if m.baseline == "fresh":
        d2, r_hat_next = student_rollout(trainer, state.student.actor, state.normalizer, k_d2)
        state = trainer.store(state, d2)
        student_states = jnp.concatenate([d1.obs, d2.obs])
    else:
        r_hat_next = r_hat_lookahead
        student_states = d1.obs
    tstate = tstate.replace(r_hat=r_hat_next)
    state = state.replace(explorer=tstate,
                          visits=visits_lib.record(state.visits, explore_obs=d0.obs, student_obs=student_states))

    # Teacher diagnostics on D0 (with the teacher before its update, which produced D0).
    _, log_std = teacher.distribution(params_d0, student.actor, d0_obs_n)
    student_action = learner.actor_apply(student.actor, d0_obs_n)
    ret_mean, n_eps = completed_episode_mean(d0_stats)
    metrics = {
        **train_metrics,
        "lookahead_critic_loss": look_metrics["critic_loss"],
        "train_return": ret_mean, "train_episodes": n_eps,
        "meta_reward": meta_reward,
        "r_hat_pi": r_hat_pi,
        "r_hat_lookahead": r_hat_lookahead,
        "teacher_log_std": jnp.mean(log_std),
        "teacher_entropy": jnp.mean(teacher.entropy(log_std)),
        "teacher_student_distance": jnp.sqrt(jnp.mean(jnp.square(d0.action - student_action))),
    }
    return state, metrics
