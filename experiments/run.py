"""Train many seeds of DDPG or Meta (DDPG + learned exploration teacher) in one compiled program.

    python -m experiments.run --env=inverted_double_pendulum --seeds=8
    python -m experiments.run --env=pendulum --method=ddpg --noise=ou --steps=90000
    python -m experiments.run --env=hopper --preset=modern --set ddpg.actor_lr=1e-3

Writes under ``--out`` (default ``runs/<env>-<method>-<preset>-s<seed>``):
``config.json``, ``metrics.jsonl`` (one line per seed per evaluation, appended
as the run goes), ``cycles.jsonl`` (meta: per-cycle teacher metrics per seed),
``learning_curve.png`` (mean ± std band and per-seed lines), ``teacher.png``
(meta), ``summary.json``; and prints the final evaluation return per seed and
mean ± std.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import shutil
import sys
import time

import envs
from metapg_jax import config as config_lib

TEACHER_CYCLE_METRICS = ("meta_reward", "r_hat_pi", "r_hat_lookahead", "teacher_log_std",
                         "teacher_entropy", "teacher_student_distance")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m experiments.run",
        description="Train DDPG (baseline) or Meta (Algorithm 1 of Xu et al., 2018) on many seeds at once.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--env", default="pendulum", help=f"task: {', '.join(envs.TASKS)}")
    p.add_argument("--method", default="meta", help="'meta' (the paper's learned teacher) or 'ddpg' (noise baseline)")
    p.add_argument("--teacher", default=None,
                   help="meta teacher design: 'independent' (paper's best) or 'variance' (default: independent)")
    p.add_argument("--preset", default="paper", help="'paper' (2018 baselines DDPG) or 'modern' (256-256, 1 update/step)")
    p.add_argument("--noise", default=None,
                   help="DDPG exploration noise: normal, ou, adaptive-param, none (default: the preset's)")
    p.add_argument("--seeds", type=int, default=8, help="number of seeds trained at once (vmapped)")
    p.add_argument("--seed", type=int, default=0, help="base PRNG seed; seed i uses fold_in(PRNGKey(seed), i)")
    p.add_argument("--steps", type=int, default=None,
                   help="stored env steps per seed (default: the paper's budget for the task)")
    p.add_argument("--source", default="gymnasium", help="MuJoCo models: 'gymnasium' (v5 on MJX) or 'brax'")
    p.add_argument("--out", default=None, help="output folder (default runs/<env>-<method>-<preset>-s<seed>)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output folder")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="GROUP.FIELD=VALUE",
                   help="override any config field, e.g. --set ddpg.tau=0.005 --set run.eval_every=3000 "
                        "(groups: env, run, ddpg, noise, meta; see metapg_jax/config.py)")
    p.add_argument("--no-plot", action="store_true", help="skip the PNG plots")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def parse_overrides(items: list[str]) -> dict[str, str]:
    out = {}
    for item in items:
        if "=" not in item:
            raise ValueError(f"--set expects GROUP.FIELD=VALUE, got {item!r}")
        k, v = item.split("=", 1)
        out[k.strip()] = v.strip()
    return out


def config_from_args(args: argparse.Namespace) -> config_lib.Config:
    """Builds and validates the config; raises ValueError with one line on bad input."""
    if args.seeds <= 0:
        raise ValueError(f"--seeds must be positive, got {args.seeds}")
    if args.steps is not None and args.steps <= 0:
        raise ValueError(f"--steps must be positive, got {args.steps}")
    if args.method == "ddpg" and args.teacher is not None:
        raise ValueError("--teacher applies to --method=meta only")
    cfg = config_lib.make_config(env=args.env, method=args.method, preset=args.preset, noise=args.noise,
                                 steps=args.steps, source=args.source, teacher=args.teacher,
                                 overrides=parse_overrides(args.overrides))
    return config_lib.validate(cfg)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        cfg = config_from_args(args)
        out = args.out or os.path.join("runs", f"{cfg.env.name}-{cfg.run.method}-{cfg.preset}-s{args.seed}")
        if os.path.exists(out) and os.listdir(out) and not args.overwrite:
            raise ValueError(f"output folder {out} exists; pass --overwrite to replace it or --out elsewhere")
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    return run(cfg, args.seeds, args.seed, out, overwrite=args.overwrite, plot=not args.no_plot,
               quiet=args.quiet)


def run(cfg: config_lib.Config, num_seeds: int, seed: int, out: str, overwrite: bool = False,
        plot: bool = True, quiet: bool = False) -> int:
    import jax
    import numpy as np

    from metapg_jax import reporting, replay
    from metapg_jax.train import make_train, seed_keys

    if overwrite and os.path.exists(out):
        shutil.rmtree(out)
    os.makedirs(out, exist_ok=True)
    reporting.write_json_atomic(os.path.join(out, "config.json"), {
        "config": dataclasses.asdict(cfg), "num_seeds": num_seeds, "seed": seed,
        "jax_version": jax.__version__, "backend": jax.default_backend(),
        "devices": [str(d) for d in jax.devices()]})

    trainer = make_train(cfg)
    keys = seed_keys(seed, num_seeds)
    name = f"{cfg.env.name} {cfg.run.method}" + (f"/{cfg.meta.teacher}" if cfg.run.method == "meta" else
                                                  f"/{cfg.noise.kind}")
    print(f"{name} ({cfg.preset} preset, {cfg.env.source} source): {num_seeds} seeds x "
          f"{cfg.run.total_steps:,} env steps, {cfg.num_chunks} evaluations every {cfg.run.eval_every:,} steps "
          f"({cfg.cycles_per_chunk} cycles of {cfg.steps_per_cycle} steps); output {out}", flush=True)

    t0 = time.perf_counter()
    state = jax.jit(jax.vmap(trainer.init))(keys)
    chunk_fn = jax.jit(jax.vmap(trainer.train_chunk), donate_argnums=0).lower(state).compile()
    compile_s = time.perf_counter() - t0
    buffer_mb = num_seeds * replay.nbytes(jax.tree.map(lambda x: x[0], state.buffer)) / 2**20
    print(f"compiled in {compile_s:.1f} s; replay buffers {buffer_mb:,.0f} MiB", flush=True)

    metrics_writer = reporting.JsonlWriter(os.path.join(out, "metrics.jsonl"))
    cycle_writer = reporting.JsonlWriter(os.path.join(out, "cycles.jsonl")) if cfg.run.method == "meta" else None
    progress = reporting.Progress(cfg.run.total_steps, num_seeds, name, disable=quiet)
    rows: list[dict] = []
    t_train = time.perf_counter()
    try:
        for chunk in range(cfg.num_chunks):
            state, metrics = chunk_fn(state)
            metrics = jax.device_get(metrics)
            new_rows = reporting.chunk_rows(metrics, chunk, time.perf_counter() - t_train)
            metrics_writer.write(new_rows)
            rows.extend(new_rows)
            if cycle_writer is not None:
                cycle_writer.write(reporting.cycle_rows(metrics, TEACHER_CYCLE_METRICS,
                                                        chunk * cfg.cycles_per_chunk))
            progress.update(int(metrics["env_steps"][0]), metrics["eval_return"].mean(1))
    finally:
        progress.close()
        metrics_writer.close()
        if cycle_writer is not None:
            cycle_writer.close()
    train_s = time.perf_counter() - t_train

    summary = reporting.summarize(rows)
    summary.update({
        "method": cfg.run.method, "env": cfg.env.name, "preset": cfg.preset, "source": cfg.env.source,
        "compile_seconds": round(compile_s, 2), "train_seconds": round(train_s, 2),
        "env_steps_per_second_total": round(num_seeds * cfg.run.total_steps / train_s, 1),
        "replay_mib": round(buffer_mb, 1), "peak_rss_mib": round(_peak_rss_mib(), 1),
    })
    reporting.write_json_atomic(os.path.join(out, "summary.json"), summary)
    if plot:
        title = f"{name}, {cfg.preset} preset: {num_seeds} seeds"
        reporting.plot_learning_curve(rows, os.path.join(out, "learning_curve.png"), title)
        if cfg.run.method == "meta":
            from experiments.plots import plot_teacher

            plot_teacher(reporting.read_jsonl(os.path.join(out, "cycles.jsonl")),
                         os.path.join(out, "teacher.png"), title)
    for i, v in enumerate(summary["final_eval_return_per_seed"]):
        print(f"seed {i}: final eval return {v:.1f}")
    print(f"{name}: final eval return {summary['final_eval_return_mean']:.1f} ± "
          f"{summary['final_eval_return_std']:.1f} (mean ± std over {num_seeds} seeds, "
          f"{summary['env_steps']:,} env steps); {summary['env_steps_per_second_total']:,.0f} env steps/s total, "
          f"compile {compile_s:.1f} s, peak RSS {summary['peak_rss_mib']:,.0f} MiB")
    return 0


def _peak_rss_mib() -> float:
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


if __name__ == "__main__":
    sys.exit(main())
