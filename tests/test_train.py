"""The compiled training loop: one compile, finite state, chunked == single scan, learning."""

import functools

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from metapg_jax.config import make_config
from metapg_jax.train import make_train, seed_keys, vmap_seeds
from tests import RUN_FAST, golden
from tests.helpers import tiny_config


def _strip_nan(state):
    # R_hat is NaN until the first estimate; everything else must be finite.
    return state.replace(explorer=state.explorer.replace(r_hat=jnp.zeros_like(state.explorer.r_hat))) \
        if hasattr(state.explorer, "r_hat") else state


@functools.lru_cache(maxsize=None)
def _program(case):
    """A golden case's trainer and its single-scan program (``train``, seeds vmapped): compiled once per
    process for the tests here that run it."""
    trainer = make_train(golden.case_config(case))
    return trainer, jax.jit(vmap_seeds(trainer.train))


# The single scan is compared on DDPG (whose program the seed-count and parameter-noise tests below run too),
# on Meta with MuJoCo's C engine (host calls inside the nested scans) and on SAC exploring with its own policy
# and colored noise (a per-episode sequence in the explorer's state); Pendulum Meta runs its chunks only.
# ``Trainer.train`` is the scan of ``train_chunk`` whatever the student and explorer (TD3: tests/test_td3.py).
SINGLE_SCAN = {"pendulum-ddpg-adaptive-param", "idp-meta-independent-mujoco", "pendulum-own-pink-sac"}


@pytest.mark.slow
@pytest.mark.parametrize("case", ["pendulum-ddpg-adaptive-param", "pendulum-meta-independent",
                                  "idp-meta-independent-mujoco", "pendulum-own-pink-sac"])
def test_chunked_and_single_scan_agree(case):
    """The chunk compiles once and its state stays finite; the chunks give the case's stored numbers
    (tests/golden.py); for the cases in ``SINGLE_SCAN`` the same key gives the same numbers twice and chunked
    equals the single scan. Also on MuJoCo's C engine (envs/mujoco_c.py), whose state is float64 words and
    whose steps are host calls (with Meta, whose cycle steps every kind of rollout)."""
    trainer = _program(case)[0] if case in SINGLE_SCAN else make_train(golden.case_config(case))
    cfg = trainer.config
    if cfg.env.physics == "mujoco":
        assert trainer.env.unwrapped.backend == "mujoco"
    chunk = jax.jit(vmap_seeds(chex.assert_max_traces(n=1)(trainer.train_chunk)))
    state, metrics = golden.run_chunks(trainer, chunk=chunk)
    chex.clear_trace_counter()
    golden.assert_stored(case, golden.numbers(state, metrics))
    chex.assert_tree_all_finite(_strip_nan(state))
    assert int(state.env_steps[0]) == cfg.run.total_steps
    if case not in SINGLE_SCAN:
        return
    train = _program(case)[1]
    keys = seed_keys(*golden.KEYS)
    full_state, full_metrics = train(keys)
    for a, b in zip(jax.tree.leaves((full_state, full_metrics)), jax.tree.leaves(train(keys))):
        np.testing.assert_array_equal(a, b)
    returns = [np.asarray(m["eval_return"]) for m in metrics]
    np.testing.assert_allclose(np.stack(returns, 1), full_metrics["eval_return"], rtol=1e-5, atol=1e-4)
    # The two programs round differently (XLA fuses them differently); on the C engine's float64 physics a
    # last-bit difference in an action grows over the episode more than on Pendulum: measured 1.4e-5 on one
    # weight of Inverted Pendulum.
    atol = 1e-5 if cfg.env.physics == "mjx" else 1e-4
    jax.tree.map(lambda a, b: np.testing.assert_allclose(a, b, rtol=1e-5, atol=atol),
                 state.student.actor, full_state.student.actor)


@pytest.mark.slow
def test_seeds_differ_and_do_not_depend_on_seed_count():
    trainer, train = _program("pendulum-ddpg-adaptive-param")
    s2, _ = train(seed_keys(0, 2))
    s1, _ = jax.jit(vmap_seeds(trainer.train))(seed_keys(0, 1))
    k = lambda s: np.asarray(s.student.actor["params"]["dense_0"]["kernel"])
    assert not np.allclose(k(s2)[0], k(s2)[1])
    np.testing.assert_allclose(k(s2)[0], k(s1)[0], rtol=1e-6)


def test_warmup_uses_random_actions_and_skips_updates():
    cfg = tiny_config("ddpg", steps=300, **{"run.warmup_steps": 200})
    trainer = make_train(cfg)
    state = trainer.init(jax.random.PRNGKey(0))
    cycle = jax.jit(trainer.cycle)
    for _ in range(3):        # 150 steps: inside the warm-up, no updates
        state, m = cycle(state)
    assert int(state.updates) == 0 and np.isnan(float(m["critic_loss"]))
    state, m = cycle(state)   # 200 stored steps: the warm-up is over, updates start
    assert int(state.updates) == cfg.run.train_steps and np.isfinite(float(m["critic_loss"]))


def _learning_run(method, steps, seeds=8):
    cfg = make_config("pendulum", method, steps=steps, overrides={"run.eval_every": 3000})
    trainer = make_train(cfg)
    _, metrics = jax.jit(vmap_seeds(trainer.train), compiler_options=RUN_FAST)(seed_keys(0, seeds))
    return np.asarray(metrics["eval_return"]).mean(-1)  # (seeds, evals)


def _random_policy_return(seeds=8):
    import envs
    from metapg_jax.evaluate import evaluate

    env = envs.make("pendulum")
    act = lambda obs: jnp.zeros(1)  # any fixed action is as bad as random on pendulum
    ret, _ = jax.vmap(lambda k: evaluate(env, act, k, 10, 200))(seed_keys(0, seeds))
    return float(ret.mean())


@pytest.mark.slow
def test_ddpg_learns_pendulum():
    returns = _learning_run("ddpg", 9000)
    baseline = _random_policy_return()
    assert baseline < -900
    # Mean over 8 seeds of the final evaluation: clearly above a policy that does nothing.
    assert returns[:, -1].mean() > baseline + 500, (returns, baseline)
    assert returns[:, -1].mean() > returns[:, 0].mean()


@pytest.mark.slow
def test_meta_learns_pendulum():
    returns = _learning_run("meta", 15000)
    baseline = _random_policy_return()
    assert returns[:, -1].mean() > baseline + 500, (returns, baseline)


def test_any_over_seeds_reduces_the_named_seed_axis_only():
    from metapg_jax.seeds import any_over_seeds

    flags = jnp.array([False, True, False])
    np.testing.assert_array_equal(vmap_seeds(any_over_seeds)(flags), [True, True, True])
    np.testing.assert_array_equal(jax.vmap(any_over_seeds)(flags), flags)  # unnamed axis: per seed
    assert not bool(jax.jit(any_over_seeds)(jnp.array(False)))  # no vmap at all


@pytest.mark.slow
def test_param_noise_episode_starts_same_numbers_with_named_seed_axis():
    # vmap_seeds draws a new actor perturbation only on steps where some seed starts an episode;
    # a plain vmap draws it at every step and keeps it where an episode starts. Same numbers.
    trainer, train = _program("pendulum-ddpg-adaptive-param")
    assert trainer.config.noise.kind == "adaptive-param"
    a = train(seed_keys(0, 2))
    b = jax.jit(jax.vmap(trainer.train))(seed_keys(0, 2))
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b)):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    perturbed = a[0].explorer.perturbed
    assert not all(np.array_equal(p, q) for p, q in zip(jax.tree.leaves(perturbed),
                                                          jax.tree.leaves(a[0].student.actor)))


@pytest.mark.parametrize("task", ["pendulum", "inverted_pendulum", "inverted_double_pendulum", "hopper",
                                  "halfcheetah", "reacher"])
def test_paper_schedules_per_task(task):
    # Meta: the paper's per-task cycle (IP and HalfCheetah: explore 1000, eval 2000, 500 updates, 100 teacher
    # steps); the DDPG baseline: baselines' 100 rollout steps and 50 updates per cycle on every task.
    big = task in ("inverted_pendulum", "halfcheetah")
    meta = make_config(task, "meta")
    assert (meta.meta.explore_steps, meta.meta.eval_steps, meta.run.train_steps, meta.meta.teacher_steps) == \
        ((1000, 2000, 500, 100) if big else (100, 200, 50, 1))
    for noise in ("adaptive-param", "normal"):
        ddpg = make_config(task, "ddpg", noise=noise)
        assert (ddpg.run.rollout_steps, ddpg.run.train_steps) == (100, 50)
    assert make_config(task, "ddpg", overrides={"run.train_steps": 7}).run.train_steps == 7


@pytest.mark.parametrize("task", ["pendulum", "inverted_pendulum", "hopper", "halfcheetah"])
def test_tuned_preset_is_the_paper_schedule_with_ddpgs_update_ratio_and_one_teacher_step(task):
    from experiments.ablation import config_diff
    from experiments.grid.methods import BASELINES
    from metapg_jax.config import PRESETS, to_dict
    from metapg_jax.strategies.meta import TUNED_META

    assert set(BASELINES) == set(PRESETS)
    paper, tuned = make_config(task, "meta"), make_config(task, "meta", "tuned")
    diff = config_diff(to_dict(tuned), to_dict(paper))
    assert set(diff) - {"meta.teacher_steps"} == {"preset", *TUNED_META} - {"meta.teacher_steps"}
    # DDPG's 50 updates per 100 stored steps for the student; the look-ahead keeps the paper's count.
    assert tuned.run.train_steps * 2 == paper.steps_per_cycle
    assert tuned.meta.lookahead_steps == paper.run.train_steps and tuned.meta.teacher_steps == 1
    assert tuned.run.eval_every == paper.run.eval_every
    for noise in ("adaptive-param", "normal"):  # the baselines are the paper preset's
        assert config_diff(to_dict(make_config(task, "ddpg", "tuned", noise=noise)),
                           to_dict(make_config(task, "ddpg", noise=noise))) == {"preset": ("tuned", "paper")}
    # A field named with --set is left as set; a longer cycle (a second D1 env) keeps the ratio.
    assert make_config(task, "meta", "tuned", overrides={"meta.teacher_steps": 5}).meta.teacher_steps == 5
    two = make_config(task, "meta", "tuned", overrides={"meta.eval_envs": 2})
    assert two.run.train_steps * 2 == two.steps_per_cycle


def test_the_replay_buffer_is_never_copied_in_a_cycle():
    """The buffer is written in place and the minibatches gather from it: the compiled chunk holds no
    copy of a buffer-sized array. (With one seed, XLA once fused the gathers with the write and then
    copied the whole buffer at every cycle, which halved the modern preset's one-step cycles at 1M
    capacity; structure, not time.)"""
    capacity = 7919  # a size no other array has
    cfg = make_config("pendulum", "ddpg", "modern", steps=400, overrides={
        "run.buffer_size": capacity, "run.warmup_steps": 100, "ddpg.hidden": "16,16", "run.eval_episodes": 1,
        "run.eval_every": 200})
    trainer = make_train(cfg)
    state = jax.eval_shape(vmap_seeds(trainer.init), seed_keys(0, 1))  # 1 seed: where the copies were
    hlo = jax.jit(vmap_seeds(trainer.train_chunk), donate_argnums=0).lower(state).compile().as_text()
    copies = [line.strip() for line in hlo.splitlines()
              if f"{capacity}" in line.split("=", 1)[-1].split("(", 1)[0] and " copy(" in line]
    assert not copies, copies[:3]
