"""The teacher and Algorithm 1: log-prob gradients, REINFORCE direction, look-ahead isolation, accounting."""

import functools
import types

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from metapg_jax.strategies import meta
from metapg_jax.config import DDPGConfig, validate
from metapg_jax.strategies.ddpg import DDPG
from metapg_jax.strategies.meta import MetaConfig
from metapg_jax import teacher as teacher_lib
from metapg_jax.strategies.bandit import BanditConfig
from metapg_jax.strategies.residual import ResidualConfig
from metapg_jax.train import make_train
from tests.helpers import tiny_config

DESIGNS = [("independent", True), ("variance", True), ("variance", False), ("residual", True)]


@functools.lru_cache(maxsize=None)
def _tiny_meta():
    """The tiny Meta config's trainer and its jitted cycle (one seed), compiled once per process for the
    tests here that run it."""
    trainer = make_train(tiny_config("meta", steps=600))
    return trainer, jax.jit(trainer.cycle)


# Two more tiny Meta configs, each shared by two tests (one compile each): a fresh-baseline run whose teacher
# does not learn, and a two-env look-ahead run that updates the student only in the look-ahead.
FRESH_FROZEN = (("meta.baseline", "fresh"), ("meta.eval_envs", 1), ("meta.lr", 0.0))
LOOKAHEAD_ONLY = (("meta.baseline", "lookahead"), ("meta.eval_envs", 2), ("run.warmup_steps", 10_000),
                  ("meta.student_from", "lookahead"))
# The bandit teacher with the paired baseline over two eval envs (shared by the paired tests).
PAIRED_BANDIT = (("meta.baseline", "paired"), ("meta.eval_envs", 2), ("meta.teacher", "bandit"))


@functools.lru_cache(maxsize=None)
def _tiny_cycle(overrides):
    """The tiny Meta config with ``overrides`` (pairs), its steps sized for four cycles: trainer, jitted cycle."""
    o = dict(overrides)
    per_cycle = 50 + 100 * o.get("meta.eval_envs", 1) * (2 if o.get("meta.baseline") in ("fresh", "paired") else 1)
    trainer = make_train(tiny_config("meta", steps=4 * per_cycle, eval_every=2 * per_cycle, **o))
    return trainer, jax.jit(trainer.cycle)


def _teacher(design, state_dependent, bandit=BanditConfig(), **kw):
    """A design (``teacher_lib.make``) for a 3-d observation, 2-d action DDPG student, and that student's actor."""
    ddpg = DDPG(DDPGConfig(hidden=(8, 8)), obs_size=3, action_size=2)
    cfg = MetaConfig(teacher=design, state_dependent_std=state_dependent, hidden=(8, 8), **kw)
    config = types.SimpleNamespace(meta=cfg, residual=ResidualConfig(), bandit=bandit, episode_length=64)
    return teacher_lib.make(config, ddpg), ddpg.init(jax.random.PRNGKey(5)).actor


@pytest.mark.parametrize("design,state_dependent", DESIGNS)
def test_log_prob_gradient_matches_finite_differences(design, state_dependent):
    teacher, actor = _teacher(design, state_dependent)
    params = teacher.init(jax.random.PRNGKey(0)).params
    key = jax.random.PRNGKey(1)
    obs = jax.random.normal(key, (6, 3))
    _, raw = teacher.sample(params, actor, obs, key)
    with jax.enable_x64(True):
        p64 = jax.tree.map(lambda x: jnp.asarray(x, jnp.float64), params)
        obs64, raw64 = jnp.asarray(obs, jnp.float64), jnp.asarray(raw, jnp.float64)
        a64 = jax.tree.map(lambda x: jnp.asarray(x, jnp.float64), actor)
        f = lambda p: jnp.sum(teacher.log_prob(p, a64, obs64, raw64))
        grad = jax.grad(f)(p64)
        for i in range(3):
            leaves, tdef = jax.tree.flatten(p64)
            ks = jax.random.split(jax.random.PRNGKey(10 + i), len(leaves))
            d = jax.tree.unflatten(tdef, [jax.random.normal(k, x.shape, jnp.float64) for k, x in zip(ks, leaves)])
            eps = 1e-5
            fd = (f(jax.tree.map(lambda p, v: p + eps * v, p64, d)) - f(jax.tree.map(lambda p, v: p - eps * v, p64, d))) / (2 * eps)
            an = sum(jnp.sum(g * v) for g, v in zip(jax.tree.leaves(grad), jax.tree.leaves(d)))
            np.testing.assert_allclose(an, fd, rtol=1e-6, atol=1e-8)


def test_log_prob_is_the_gaussian_density_of_the_unclipped_sample():
    teacher, actor = _teacher("independent", True, init_log_std=0.3)
    params = teacher.init(jax.random.PRNGKey(0)).params
    obs = jnp.ones((3,))
    action, raw = teacher.sample(params, actor, obs, jax.random.PRNGKey(2))
    mean, log_std = teacher.distribution(params, actor, obs)
    np.testing.assert_allclose(log_std, 0.3, atol=0.01)   # starts at init_log_std
    sd = np.exp(np.asarray(log_std))
    expected = np.sum(-0.5 * ((np.asarray(raw) - np.asarray(mean)) / sd) ** 2 - np.log(sd) - 0.5 * np.log(2 * np.pi))
    np.testing.assert_allclose(teacher.log_prob(params, actor, obs, raw), expected, rtol=1e-5)
    np.testing.assert_array_equal(action, np.clip(raw, -1, 1))
    # Log-std stays inside its bounds whatever the network says.
    assert float(teacher.squash_log_std(jnp.asarray(1e6))) == pytest.approx(teacher.cfg.max_log_std)
    assert float(teacher.squash_log_std(jnp.asarray(-1e6))) == pytest.approx(teacher.cfg.min_log_std)


def _reinforce_toy(sign, design="independent"):
    """A one-step problem: meta reward = sign * (1 - |a - target|^2); D0 = 8 actions at one state."""
    teacher, actor = _teacher(design, True, lr=3e-3, init_log_std=-1.0)
    target = jnp.array([0.6, -0.4])
    obs = jnp.tile(jnp.array([0.2, -0.1, 0.3]), (8, 1))

    def it(state, key):
        _, raw = teacher.sample(state.params, actor, obs, key)
        reward = sign * (1.0 - jnp.mean(jnp.sum(jnp.square(jnp.clip(raw, -1, 1) - target), -1)))
        state, centred = teacher.normalize_reward(state, reward)  # a running baseline for variance reduction
        return teacher.update(state, actor, obs, raw, centred), None

    state = teacher.init(jax.random.PRNGKey(0))
    mean0 = teacher.distribution(state.params, actor, obs[0])[0]
    state, _ = jax.lax.scan(it, state, jax.random.split(jax.random.PRNGKey(1), 400))
    mean1 = teacher.distribution(state.params, actor, obs[0])[0]
    return float(jnp.linalg.norm(mean0 - target)), float(jnp.linalg.norm(mean1 - target))


def test_reinforce_moves_teacher_toward_higher_meta_reward():
    before, after = _reinforce_toy(+1.0)
    assert after < before - 0.2, (before, after)
    before, after = _reinforce_toy(-1.0)
    assert after > before + 0.2, (before, after)


@pytest.mark.parametrize("design", ["variance", "residual"])
def test_a_teacher_around_the_student_never_changes_the_student(design):
    teacher, actor = _teacher(design, True)
    state = teacher.init(jax.random.PRNGKey(0))
    obs = jax.random.normal(jax.random.PRNGKey(1), (5, 3))
    _, raw = teacher.sample(state.params, actor, obs, jax.random.PRNGKey(2))
    g_actor = jax.grad(teacher.reinforce_loss, argnums=1)(state.params, actor, obs, raw, 3.0)
    assert all(float(jnp.abs(g).max()) == 0.0 for g in jax.tree.leaves(g_actor))
    g_teacher = jax.grad(teacher.reinforce_loss)(state.params, actor, obs, raw, 3.0)
    assert any(float(jnp.abs(g).max()) > 0.0 for g in jax.tree.leaves(g_teacher))
    # the mean is the student's (plus the residual's offset): no parameters of its own for it
    assert set(state.params) == {"variance": {"log_std"}, "residual": {"log_std", "offset"}}[design]


@pytest.mark.parametrize("student_from", ["pi", "lookahead"])
def test_lookahead_does_not_touch_the_student(student_from):
    # With the warm-up longer than the run, the student's own updates are skipped; so any change
    # of the student comes from the look-ahead, which must only happen with student_from=lookahead.
    if student_from == "lookahead":
        trainer, cycle = _tiny_cycle(LOOKAHEAD_ONLY)
    else:
        trainer = make_train(tiny_config("meta", steps=300, **{"run.warmup_steps": 10_000, "meta.student_from": "pi"}))
        cycle = jax.jit(trainer.cycle)
    assert trainer.config.meta.student_from == student_from and trainer.config.run.warmup_steps == 10_000
    state = trainer.init(jax.random.PRNGKey(0))
    new, metrics = cycle(state)
    same = jax.tree.leaves(jax.tree.map(lambda a, b: bool(np.array_equal(a, b)), state.student, new.student))
    assert all(same) == (student_from == "pi")
    assert np.isfinite(float(metrics["r_hat_lookahead"]))


def test_a_zero_learning_rate_freezes_the_teacher_and_nothing_else():
    trainer, cycle = _tiny_cycle(FRESH_FROZEN)
    assert trainer.config.meta.lr == 0.0
    state = trainer.init(jax.random.PRNGKey(0))
    new = cycle(cycle(state)[0])[0]
    assert all(jax.tree.leaves(jax.tree.map(np.array_equal, state.explorer.params, new.explorer.params)))
    assert not all(jax.tree.leaves(jax.tree.map(np.array_equal, state.student.actor, new.student.actor)))
    learner, learn = _tiny_meta()  # a run with the preset's lr: the teacher moves
    learning = learn(learn(learner.init(jax.random.PRNGKey(0)))[0])[0]
    assert not all(jax.tree.leaves(jax.tree.map(np.array_equal, state.explorer.params, learning.explorer.params)))
    with pytest.raises(ValueError, match="meta.lr must be a finite number >= 0"):
        validate(tiny_config("meta", steps=300, **{"meta.lr": -1e-4}))


@pytest.mark.parametrize("baseline,eval_envs", [("lookahead", 1), ("lookahead", 2), ("fresh", 1), ("paired", 2)])
def test_sample_accounting(baseline, eval_envs):
    """Samples per cycle: explore_steps, plus eval_steps per evaluation env for D1 (twice with a fresh or paired
    baseline). (The teacher, its learning rate, the warm-up and where the student comes from do not change them.)"""
    per_cycle = 50 + 100 * eval_envs * (2 if baseline in ("fresh", "paired") else 1)
    trainer, cycle = {("lookahead", 1): _tiny_meta, ("lookahead", 2): lambda: _tiny_cycle(LOOKAHEAD_ONLY),
                      ("fresh", 1): lambda: _tiny_cycle(FRESH_FROZEN),
                      ("paired", 2): lambda: _tiny_cycle(PAIRED_BANDIT)}[baseline, eval_envs]()
    cfg = trainer.config
    assert (cfg.meta.baseline, cfg.meta.eval_envs) == (baseline, eval_envs)
    state = trainer.init(jax.random.PRNGKey(0))
    n = 2
    for _ in range(n):
        state, m = cycle(state)
    assert cfg.steps_per_cycle == per_cycle
    assert int(state.env_steps) == n * per_cycle == int(state.buffer.size)
    assert int(state.visits.explore_count) == n * 50


def test_first_episode_return_truncates_at_the_first_end():
    r = jnp.array([1.0, 2.0, 3.0, 4.0, 5.0])
    assert float(meta.first_episode_return(r, jnp.array([0.0, 0.0, 1.0, 0.0, 1.0]))) == 6.0
    assert float(meta.first_episode_return(r, jnp.zeros(5))) == 15.0


def test_meta_reward_is_zero_until_a_baseline_exists_then_the_difference():
    trainer, cycle = _tiny_meta()
    state = trainer.init(jax.random.PRNGKey(0))
    state, m0 = cycle(state)
    assert float(m0["meta_reward"]) == 0.0
    state, m1 = cycle(state)
    np.testing.assert_allclose(m1["meta_reward"], m1["r_hat_lookahead"] - m0["r_hat_lookahead"], rtol=1e-5)
    np.testing.assert_allclose(m1["r_hat_pi"], m0["r_hat_lookahead"])


@pytest.mark.parametrize("preset,normalize", [("paper", True), ("modern", False)])
def test_meta_cycle_runs_with_both_presets_and_reward_normalisation(preset, normalize):
    from metapg_jax.config import make_config

    cfg = make_config("pendulum", "meta", preset, steps=900, overrides={
        "run.eval_every": 900, "meta.explore_steps": 50, "meta.eval_steps": 100, "ddpg.hidden": "32,32",
        "meta.hidden": "32,32", "meta.normalize_meta_reward": normalize, "meta.visit_samples": 16})
    assert cfg.run.train_steps == (150 if preset == "modern" else 50)
    trainer = make_train(cfg)
    state = trainer.init(jax.random.PRNGKey(0))
    cycle = jax.jit(trainer.cycle)
    for _ in range(3):
        state, m = cycle(state)
    assert np.isfinite(float(m["meta_reward"])) and np.isfinite(float(m["critic_loss"]))
    if normalize:
        assert int(state.explorer.reward_count) == 2   # the first cycle has no meta reward to normalise


def test_the_paired_baseline_is_the_student_itself_from_the_resets_of_d1():
    """R_hat(pi) is the cycle's own student from D1's resets (the same key: the same start states), so the meta
    reward is the look-ahead's gain from the first cycle on; the noise metrics are the spreads over the envs."""
    trainer, cycle = _tiny_cycle(PAIRED_BANDIT)
    state = trainer.init(jax.random.PRNGKey(3))
    rewards = []
    for i in range(2):
        k_d1 = jax.random.split(state.key, 6)[3]
        _, returns = meta.student_rollout(trainer, state.student.actor, state.normalizer, k_d1)
        again = meta.student_rollout(trainer, state.student.actor, state.normalizer, k_d1)[1]
        np.testing.assert_array_equal(returns, again)
        state, m = cycle(state)
        np.testing.assert_allclose(m["r_hat_pi"], np.mean(returns), rtol=1e-6)
        np.testing.assert_allclose(m["meta_reward"], m["r_hat_lookahead"] - m["r_hat_pi"], rtol=1e-5, atol=1e-4)
        assert np.isfinite(float(m["meta_reward_sd_paired"])) and float(m["meta_reward_sd_unpaired"]) > 0
        rewards.append(float(m["meta_reward"]))
    # The bandit in the cycle: its first two arms pulled once each, each valued at its cycle's meta reward (paired:
    # the first cycle has a baseline), the arm's scale in the cycle's teacher_log_std.
    bandit = state.explorer.params
    np.testing.assert_array_equal(bandit["pulls"], [1, 1, 0, 0])
    np.testing.assert_allclose(bandit["values"], [*rewards, 0, 0], rtol=1e-6)
    assert float(m["teacher_log_std"]) == pytest.approx(np.log(trainer.config.bandit.scales[1]))
    _, m = _tiny_meta()[1](_tiny_meta()[0].init(jax.random.PRNGKey(3)))  # one eval env, unpaired: no noise measure
    assert np.isnan(float(m["meta_reward_sd_paired"])) and np.isnan(float(m["meta_reward_sd_unpaired"]))


def test_the_residual_teacher_starts_at_the_student_and_stays_within_its_bound():
    teacher, actor = _teacher("residual", True, init_log_std=-2.0)
    state = teacher.init(jax.random.PRNGKey(0))
    obs = jax.random.normal(jax.random.PRNGKey(1), (16, 3))
    student = teacher.student.actor_apply(actor, obs)
    mean, log_std = teacher.distribution(state.params, actor, obs)
    np.testing.assert_array_equal(mean, student)            # the offset's last layer starts at zero
    np.testing.assert_allclose(log_std, -2.0, atol=0.05)        # its log-std net starts near init_log_std
    big = jax.tree.map(lambda x: 1e3 * jax.random.normal(jax.random.PRNGKey(2), x.shape), state.params["offset"])
    far = teacher.distribution({**state.params, "offset": big}, actor, obs)[0]
    assert float(jnp.max(jnp.abs(far - student))) <= teacher.max_offset + 1e-6
    assert float(jnp.max(jnp.abs(far - student))) > 0.9 * teacher.max_offset
    # The teacher mean's distance from the student, its noise left out: 0 at the start, the offset's RMS once moved
    # (the clipped mean's: near a student's action at the range's edge, part of the offset is cut off).
    assert float(teacher.diagnostics(state.params, actor, obs)["teacher_mean_distance"]) == 0.0
    moved = teacher.diagnostics({**state.params, "offset": big}, actor, obs)["teacher_mean_distance"]
    np.testing.assert_allclose(moved, np.sqrt(np.mean(np.square(np.clip(far, -1, 1) - student))), rtol=1e-5)
    # REINFORCE moves the offset toward the rewarded actions (the student's action is near 0, the target 0.72 away:
    # the bound 0.3 leaves 0.4 to gain).
    before, after = _reinforce_toy(+1.0, "residual")
    assert after < before - 0.2, (before, after)
    with pytest.raises(ValueError, match="residual.max_offset must be a finite number > 0"):
        validate(tiny_config("meta", steps=300, **{"meta.teacher": "residual", "residual.max_offset": 0}))
    with pytest.raises(ValueError, match="meta.state_dependent_std=false does not apply"):
        validate(tiny_config("meta", steps=300, **{"meta.teacher": "residual", "meta.state_dependent_std": False}))


def test_the_bandit_tries_every_arm_then_follows_its_values():
    teacher, actor = _teacher("bandit", True, bandit=BanditConfig(scales=(0.05, 0.1, 0.4), epsilon=0.0,
                                                                   step_size=0.25))
    state = teacher.init(jax.random.PRNGKey(0)).replace(r_hat=jnp.zeros(()))  # a baseline exists
    obs = jax.random.normal(jax.random.PRNGKey(1), (4000, 3))
    rewards = {0: 1.0, 1: 5.0, 2: -2.0}
    for i, k in enumerate(jax.random.split(jax.random.PRNGKey(2), 3)):
        state = teacher.begin_cycle(state, k)
        assert int(state.params["arm"]) == i                 # every arm once, in order
        _, raw = teacher.sample(state.params, actor, obs, k)
        noise = np.asarray(raw - teacher.student.actor_apply(actor, obs))
        np.testing.assert_allclose(noise.std(), teacher.bandit.scales[i], rtol=0.05)
        state = teacher.update(state, actor, obs, raw, rewards[i])
    np.testing.assert_allclose(state.params["values"], [1.0, 5.0, -2.0])  # a first pull: the reward itself
    state = teacher.begin_cycle(state, jax.random.PRNGKey(3))
    assert int(state.params["arm"]) == 1                     # greedy
    state = teacher.update(state, actor, obs, raw, 1.0)      # second pull: step max(1/2, 0.25)
    np.testing.assert_allclose(state.params["values"][1], 3.0)
    np.testing.assert_allclose(state.params["pulls"], [1, 2, 1])
    unset = teacher.update(state.replace(r_hat=jnp.full((), jnp.nan)), actor, obs, raw, 100.0)
    assert all(jax.tree.leaves(jax.tree.map(np.array_equal, unset.params, state.params)))  # no baseline: no update
    wild, _ = _teacher("bandit", True, bandit=BanditConfig(scales=(0.1, 0.2), epsilon=1.0))
    seen = wild.init(jax.random.PRNGKey(0)).params
    seen = {**seen, "pulls": jnp.ones(2)}
    arms = [int(wild.choose(seen, k)) for k in jax.random.split(jax.random.PRNGKey(4), 200)]
    assert 60 < sum(arms) < 140                              # epsilon 1: uniformly random
    assert float(wild.diagnostics(seen, actor, obs)["teacher_log_std"]) == pytest.approx(np.log(0.1))
    for bad, match in [({"bandit.scales": "-0.1"}, "bandit.scales"), ({"bandit.epsilon": 2}, "bandit.epsilon"),
                       ({"bandit.step_size": 0}, "bandit.step_size"),
                       ({"meta.normalize_meta_reward": True}, "meta.normalize_meta_reward=true does not apply")]:
        with pytest.raises(ValueError, match=match):
            validate(tiny_config("meta", steps=300, **{"meta.teacher": "bandit", **bad}))


def test_the_uniform_teacher_draws_uniform_actions_and_learns_nothing():
    teacher, actor = _teacher("uniform", True)
    state = teacher.init(jax.random.PRNGKey(0))
    obs = jax.random.normal(jax.random.PRNGKey(1), (20000, 3))
    action, raw = teacher.sample(state.params, actor, obs, jax.random.PRNGKey(2))
    assert action.shape == (20000, 2) and float(jnp.min(action)) >= -1 and float(jnp.max(action)) <= 1
    np.testing.assert_allclose(np.var(np.asarray(action), axis=0), 1 / 3, rtol=0.03)
    assert teacher.update(state, actor, obs, raw, 7.0) is state
    np.testing.assert_allclose(teacher.diagnostics(state.params, actor, obs)["teacher_mean_distance"],
                               np.sqrt(np.mean(np.square(teacher.student.actor_apply(actor, obs)))), rtol=1e-5)
    with pytest.raises(ValueError, match="unknown teacher 'nope'; valid teachers: independent, variance"):
        validate(tiny_config("meta", steps=300, **{"meta.teacher": "nope"}))


def test_the_meta_reward_spread_paired_and_unpaired():
    r1, r0 = jnp.array([10.0, 14.0, 30.0]), jnp.array([9.0, 11.0, 29.5])
    got = meta.meta_reward_spread(r1, r0)
    np.testing.assert_allclose(got["meta_reward_sd_paired"], np.std([1.0, 3.0, 0.5], ddof=1), rtol=1e-6)
    np.testing.assert_allclose(got["meta_reward_sd_unpaired"],
                               np.hypot(np.std(r1, ddof=1), np.std(r0, ddof=1)), rtol=1e-6)
    one = meta.meta_reward_spread(r1[:1], r0[:1])
    assert np.isnan(float(one["meta_reward_sd_paired"])) and np.isnan(float(one["meta_reward_sd_unpaired"]))


def test_a_colored_bandit_d0_takes_its_noise_from_one_sequence_per_episode():
    """bandit.beta=1: D0's noise is a pink sequence drawn at an episode's first step from that step's key and read
    step by step (the carry, kept across cycles in the parameters by end_d0); beta=0 is sample()'s white noise with
    no carry. A bad beta is one line before anything compiles."""
    from metapg_jax.action_noise import colored_sequence

    teacher, actor = _teacher("bandit", False, BanditConfig(scales=(0.5,), beta=1.0))
    state = teacher.init(jax.random.PRNGKey(0))
    carry, obs = teacher.d0_carry(state), jnp.full((3,), 0.3)
    mean = np.asarray(teacher.distribution(state.params, actor, obs)[0])
    keys = jax.random.split(jax.random.PRNGKey(3), 70)
    step = jax.jit(lambda c, first, k: teacher.sample_step(state.params, c, actor, obs, first, k))
    raws = []
    for t in range(70):  # episodes of 64 steps: a new one at step 64
        _, raw, carry = step(carry, jnp.asarray(t in (0, 64)), keys[t])
        raws.append(np.asarray(raw))
    z = (np.stack(raws) - mean) / 0.5
    np.testing.assert_allclose(z[:64], colored_sequence(keys[0], 1.0, 64, 2), atol=1e-5)
    np.testing.assert_allclose(z[64:], colored_sequence(keys[64], 1.0, 64, 2)[:6], atol=1e-5)
    kept = teacher.end_d0(state, carry)
    assert int(kept.params["noise"]["step"]) == 6 and teacher.d0_carry(kept) is kept.params["noise"]

    white, _ = _teacher("bandit", False, BanditConfig(scales=(0.5,)))
    w = white.init(jax.random.PRNGKey(0))
    assert white.d0_carry(w) is None and "noise" not in w.params
    _, raw, c = white.sample_step(w.params, None, actor, obs, jnp.asarray(True), keys[0])
    np.testing.assert_array_equal(raw, white.sample(w.params, actor, obs, keys[0])[1])
    assert c is None and white.end_d0(w, None) is w
    colored = meta.make_teacher(make_train(tiny_config("meta", **{"meta.teacher": "bandit", "bandit.beta": 1.0,
                                                                  "env.episode_length": 70})))
    assert (colored.bandit.beta, colored.episode_length) == (1.0, 70)  # the run's config reaches the teacher
    with pytest.raises(ValueError, match="bandit.beta must be a finite number >= 0"):
        validate(tiny_config("meta", **{"meta.teacher": "bandit", "bandit.beta": -1.0}))


@pytest.mark.slow
def test_a_run_with_a_colored_bandit_d0_resumes_bit_for_bit(tmp_path):
    """The colored sequence and its step are in the checkpoint: a run resumed mid-episode (70-step episodes) draws
    the same noise and ends with the numbers of an uninterrupted one."""
    from tests.helpers import rewind_resume_and_compare, tiny_argv

    args = [*tiny_argv("meta", **{"meta.teacher": "bandit", "bandit.scales": "0.1", "bandit.beta": 1.0,
                                  "env.episode_length": 70}), "--steps=600", "--checkpoint-every=1"]
    rewind_resume_and_compare(tmp_path, args)
