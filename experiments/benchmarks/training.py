"""Training speed, measured in one process per configuration (``python -m experiments.bench --one``):
whole training vs env stepping alone vs DDPG updates alone, memory; the seed-scaling ratio across
rows; and the training table of ``BENCHMARKS.md``."""

from __future__ import annotations

import os
import statistics
import time

from experiments.benchmarks.engines import engines_markdown
from experiments.benchmarks.records import TARGETS, _date, _variant, write_section
from experiments.benchmarks.timing import _timed


# Not metapg_jax.host.terminal.peak_rss_mib: that is the process's peak (getrusage), this is the RSS
# now (VmRSS). measure_one's growth figure is peak at the end minus the RSS after imports, and a peak
# taken as that baseline would hide any growth below an import-time spike.
def _rss_mib() -> float:
    """Current resident set size (MiB) from /proc (Linux); peak from getrusage."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    return float("nan")


def measure_one(spec: dict) -> dict:
    """All measurements for one configuration, in this process."""
    import jax
    import jax.numpy as jnp

    from metapg_jax import replay
    from metapg_jax.host import terminal
    from metapg_jax.config import make_config
    from metapg_jax.rollout import rollout
    from metapg_jax.loop import train_updates
    from metapg_jax.train import make_train, seed_keys, vmap_seeds

    rss_base = _rss_mib()
    overrides = dict(spec.get("overrides", {}))
    cfg = make_config(spec["env"], spec["method"], spec["preset"], overrides=overrides,
                      physics=spec.get("physics", "mjx"), student=spec.get("student", "ddpg"))
    env = None
    if spec.get("stock_mjx"):  # MJX's own (scanned) line search instead of our early exit, for before/after
        import envs

        env = envs.make(cfg.env.name, source=cfg.env.source, episode_length=cfg.episode_length,
                        early_exit_linesearch=False)
    trainer = make_train(cfg, env)
    seeds, repeats = spec["seeds"], spec["repeats"]
    cycles = max(1, spec["target_steps"] // cfg.steps_per_cycle)
    keys = seed_keys(0, seeds)
    updates_per_cycle = cfg.run.train_steps + (
        (cfg.meta.lookahead_steps or cfg.run.train_steps) if cfg.run.method == "meta" else 0)

    # -- whole training (cycles only) -------------------------------------------------------
    def cycles_fn(state):
        return jax.lax.scan(lambda s, _: trainer.cycle(s), state, None, length=cycles)

    state = jax.jit(vmap_seeds(trainer.init))(keys)
    t = time.perf_counter()
    # plain_vmap: an unnamed seed axis, so episode-start branches run for every seed at every step
    # (the numbers are the same; see metapg_jax.seeds.per_seed_cond): the 'before' of that change.
    seed_vmap = jax.vmap if spec.get("plain_vmap") else vmap_seeds
    full = jax.jit(seed_vmap(cycles_fn), donate_argnums=0).lower(state).compile()
    compile_s = time.perf_counter() - t
    # Warm-up: fill the buffer past the warm-up phase so every timed call does real updates.
    while int(state.env_steps[0]) < max(cfg.run.warmup_steps, cfg.ddpg.batch_size):
        state, _ = full(state)
    state, _ = full(state)
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        state, m = full(state)
        jax.block_until_ready(m)
        times.append(time.perf_counter() - t)
    full_s = statistics.median(times)
    steps = seeds * cycles * cfg.steps_per_cycle

    # -- environment stepping alone: same steps, same batch ------------------------------------
    env = trainer.env

    def random_policy(carry, obs, first, k):
        return jax.random.uniform(k, (env.action_size,), jnp.float32, -1.0, 1.0), carry, None

    def env_only(env_state, key):
        def one_cycle(s, k):
            s, _, tr, _, _ = rollout(env, random_policy, s, None, k, cfg.steps_per_cycle)
            return s, tr.reward.sum()

        return jax.lax.scan(one_cycle, env_state, jax.random.split(key, cycles))

    env_fn = jax.jit(jax.vmap(env_only))
    env_s, env_times = _timed(env_fn, (state.env_state, keys), repeats)

    # -- the same number of DDPG updates alone, on the filled buffer ---------------------------
    learner = trainer.student

    def updates_only(st, key):
        sample = lambda k: replay.sample(st.buffer, k, cfg.ddpg.batch_size)
        student, metrics = train_updates(learner, st.student, st.normalizer, sample, key,
                                            cycles * updates_per_cycle)
        return student, metrics

    upd_fn = jax.jit(jax.vmap(updates_only))
    upd_s, upd_times = _timed(upd_fn, (state, keys), repeats)

    # -- one evaluation ---------------------------------------------------------------------------
    eval_fn = jax.jit(jax.vmap(trainer.evaluate))
    eval_s, eval_times = _timed(eval_fn, (state, keys), max(1, repeats // 2))

    buffer_mib = seeds * replay.nbytes(jax.tree.map(lambda x: x[0], state.buffer)) / 2**20
    peak = terminal.peak_rss_mib()
    return {
        **{k: spec[k] for k in ("env", "method", "preset", "seeds")}, "method": spec.get("label", spec["method"]),
        "student": cfg.student, "stock_mjx": bool(spec.get("stock_mjx")),
        "physics": cfg.env.physics,
        "plain_vmap": bool(spec.get("plain_vmap")), "measured": time.strftime("%Y-%m-%d"),
        "backend": jax.default_backend(), "device": str(jax.devices()[0]),
        "cycles": cycles, "steps_per_cycle": cfg.steps_per_cycle, "updates_per_cycle": updates_per_cycle,
        "env_steps_measured": steps, "compile_s": compile_s,
        "full_s": full_s, "full_times": times, "env_s": env_s, "env_times": env_times,
        "updates_s": upd_s, "update_times": upd_times, "eval_s": eval_s, "eval_times": eval_times,
        "eval_episodes": cfg.run.eval_episodes,
        "steps_per_s_total": steps / full_s, "steps_per_s_per_seed": steps / full_s / seeds,
        "env_alone_steps_per_s": steps / env_s, "updates_alone_per_s": seeds * cycles * updates_per_cycle / upd_s,
        "overhead_ratio": full_s / (env_s + upd_s),
        "buffer_mib": buffer_mib, "peak_rss_mib": peak, "rss_growth_mib": peak - rss_base,
    }



def _row_md(r: dict, scaling: float | None) -> str:
    def f(x, fmt="{:,.0f}"):
        return "–" if x is None else fmt.format(x)

    env = r["env"] + _variant(r)
    return (f"| {env} | {r['method']} | {r['preset']} | {_date(r)} | {r['seeds']} | {f(r['compile_s'], '{:.1f}')} | "
            f"{f(r['steps_per_s_total'])} | {f(r['steps_per_s_per_seed'])} | {f(r['env_alone_steps_per_s'])} | "
            f"{f(r['updates_alone_per_s'])} | {f(r['overhead_ratio'], '{:.2f}')} | {f(scaling, '{:.2f}')} | "
            f"{f(r['eval_s'], '{:.2f}')} | {f(r['buffer_mib'])} | {f(r['rss_growth_mib'])} | "
            f"{f(r['peak_rss_mib'])} |")


def seed_scaling(rows: list[dict]) -> dict:
    """Total throughput at n seeds / at 1 seed, per (env, method, preset)."""
    group = lambda r: (r["env"], r["method"], r["preset"], _variant(r), _date(r))  # ratios within one date
    base = {group(r): r["steps_per_s_total"] for r in rows if r["seeds"] == 1}
    return {id(r): r["steps_per_s_total"] / base[group(r)] for r in rows if group(r) in base}


def write_markdown(rows: list[dict], path: str, meta: dict, section: str = "training") -> None:
    """The rows' table as the generated ``section`` of ``path`` (``training``; ``strategies`` for grid methods)."""
    import envs  # brax on import: only when the table is written

    scaling = seed_scaling(rows)
    dates = sorted({_date(r) for r in rows})
    rows = sorted(rows, key=lambda r: (envs.has_mujoco(r["env"]), r["env"], r["preset"], r["method"], _date(r),
                                       _variant(r), r["seeds"]))
    lines = [
        f"`python -m experiments.bench`, rows measured on {', '.join(dates)} ({meta['machine']}; jax {meta['jax']}, "
        f"backend {meta['backend']}; {meta['repeats']} timed repeats per number, medians). Raw numbers, every "
        f"repeat: `{os.path.basename(meta['json'])}`.", "",
        "Columns: steady-state env steps/s of whole training (cycles only, evaluation excluded) in total and per "
        "seed; env stepping alone and DDPG updates alone with the same counts and seed batch; overhead = full / "
        "(env alone + updates alone); scaling = total throughput / the 1-seed row's; one evaluation "
        "(`eval_episodes` full episodes) in seconds; replay buffers' bytes; peak RSS growth over the process "
        "after imports, and peak RSS.", "",
        f"Targets: overhead <= {TARGETS['overhead']}, 8-seed scaling >= {TARGETS['scaling_8']}x, compile <= "
        f"{TARGETS['compile_s']:.0f} s, peak memory <= {TARGETS['rss_over_buffer']}x the buffers' bytes.", "",
        "| task | method | preset | measured | seeds | compile s | steps/s total | steps/s per seed | env alone steps/s | "
        "updates alone /s | overhead | scaling | eval s | buffers MiB | RSS growth MiB | peak RSS MiB |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    lines += [_row_md(r, scaling.get(id(r))) for r in rows]
    if len(dates) > 1:
        lines += ["", "Rows of different dates may have run under different machine load: compare ratios "
                  "within a date; scaling is computed within a date."]
    lines += engines_markdown(rows)
    write_section(path, section, "\n".join(lines))

