"""Hyperparameter sweeps: every setting of a grid and every seed in one compiled program per group.

    python -m experiments.sweep --env=pendulum --method=meta --seeds=4 \\
        --grid meta.lr=1e-4,3e-4,1e-3 --grid meta.init_log_std=-1,-0.5,0     # 9 settings x 4 seeds, one program
    python -m experiments.sweep --resume runs/sweep-pendulum-meta-s0                    # continue it

Each combination of the ``--grid`` values (their cartesian product) is a *setting*: the run that
``experiments.run`` with the same options and ``--set FIELD=VALUE`` for each grid field would
train (validated as such, before anything compiles). Settings whose grid fields only enter the
computation as numbers share one program, vmapped over (settings x seeds) (``metapg_jax.sweep``);
fields that change shapes or the program's structure (network sizes, schedules, loop counts, the
teacher design, a noise kind) are found by tracing and split the settings into one program per
combination of their values, run one after another. Seeds: setting *k*'s seed *i* is the key
``experiments.run --seed S`` gives seed *i*, so a setting's numbers are those of its separate run up
to float32 round-off (another batch shape).

Writes under ``--out`` (default ``runs/sweep-<env>-<method>[-<student>]-s<seed>``):
``sweep.json`` (the options, the grid, each setting's values and program group, provenance),
``metrics.jsonl`` (``experiments.run``'s rows with a ``setting`` column, appended as chunks finish),
``summary.md`` / ``summary.json`` (per setting: final return mean ± std over seeds and its 95% CI,
the best setting marked, settings with non-finite parameters named), ``sweep.png`` (final return
per setting with its CI) and ``groups/<g>/checkpoints``. ``--resume OUT`` continues every group
from its latest checkpoint (a finished group is skipped). A setting whose parameters become
non-finite keeps running (the others are unaffected) and is reported, not ranked.

Exit status: 0 done; 2 bad input (one ``error:`` line, before anything compiles); 130 interrupted
(checkpointed; ``--resume`` continues); 143 stopped by SIGTERM (the group's chunk in flight checkpointed
within ``--term-grace``, else at once, as ``experiments.run``).
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import shutil
import sys
import time

import envs
from experiments.training import args as training_args, memory
from metapg_jax.config import current_name
from metapg_jax.host import compile_cache, runner

def sweep_args() -> tuple[str, ...]:
    """The run arguments a sweep takes (every explorer's shortcut, a preloaded plug-in's too)."""
    return ("env", "method", *training_args.flags(), "student", "preset", "seeds", "seed", "steps", "source",
            "physics", "overrides", "plugins")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m experiments.sweep",
                                description="Run a grid of config settings x seeds as one compiled program per "
                                            "group of shape-compatible settings.")
    for name in ("--env", "--method", *(f"--{flag}" for flag in training_args.flags()), "--student", "--preset",
                 "--source", "--physics"):
        p.add_argument(name, default=None, help=f"as experiments.run {name}")
    p.add_argument("--seeds", type=int, default=None, help="seeds per setting (default 8)")
    p.add_argument("--seed", type=int, default=None, help="base PRNG seed, as experiments.run (default 0)")
    p.add_argument("--steps", type=int, default=None, help="env steps per seed (default: the task's paper budget)")
    p.add_argument("--set", dest="overrides", action="append", default=None, metavar="GROUP.FIELD=VALUE",
                   help="a fixed override of every setting (as experiments.run --set)")
    p.add_argument("--plugin", dest="plugins", action="append", default=None, metavar="MODULE|FILE.py",
                   help="as experiments.run --plugin")
    p.add_argument("--grid", action="append", default=[], metavar="GROUP.FIELD=V1,V2,...",
                   help="a swept field and its values (repeatable; the settings are the cartesian product)")
    p.add_argument("--out", default=None, help="output folder (default runs/sweep-<env>-<method>[-<student>]-s<seed>)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output folder")
    p.add_argument("--resume", default=None, metavar="SWEEP_DIR", help="continue the sweep in SWEEP_DIR")
    p.add_argument("--checkpoint-minutes", type=float, default=5.0,
                   help="minimum minutes between checkpoints of a group (and at its end; default 5)")
    training_args.add_stop_options(p, "; for the group that runs")
    training_args.add_physics_threads_option(p)
    p.add_argument("--compile-cache", default=None, metavar="DIR|off", help="as experiments.run --compile-cache")
    p.add_argument("--no-plot", action="store_true", help="skip sweep.png")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def parse_grid(items: list[str]) -> dict[str, list[str]]:
    """{field: [value strings]} from ``--grid FIELD=V1,V2`` options, refusing malformed ones."""
    grid = {}
    for item in items:
        field, sep, values = item.partition("=")
        field = current_name(field.strip())  # a field that moved is swept under its current name
        if not sep or not field:
            raise ValueError(f"--grid expects GROUP.FIELD=V1,V2,..., got {item!r}")
        if field in grid:
            raise ValueError(f"--grid names {field} twice")
        # Network sizes are written 64,64: separate such values with ';' (--grid ddpg.hidden=64,64;256,256).
        vals = [v.strip() for v in (values.split(";") if ";" in values else values.split(","))]
        if not vals or any(not v for v in vals):
            raise ValueError(f"--grid {field}: empty value in {values!r}")
        if len(set(vals)) != len(vals):
            raise ValueError(f"--grid {field}: a value is given twice in {values!r}")
        grid[field] = vals
    if not grid:
        raise ValueError("give at least one --grid GROUP.FIELD=V1,V2,...")
    return grid


def plan(a: dict, grid: dict[str, list[str]]):
    """The settings (validated configs) and their program groups; raises ValueError on bad input.

    Returns (settings, configs, groups): ``settings[k]`` = {field: value string}; ``groups`` = list of
    {"settings": [k...], "batched": [fields varying within the program], "fixed": {structural field: value}}."""
    from metapg_jax.config import to_dict
    from metapg_jax.sweep import get_field, set_fields, structural_fields

    fixed = {current_name(k): v for k, v in training_args.parse_overrides(a["overrides"]).items()}
    for field in grid:
        if field in fixed:
            raise ValueError(f"{field} is both swept (--grid) and fixed (--set)")
    settings = [dict(zip(grid, values)) for values in itertools.product(*grid.values())]
    configs = []
    for s in settings:
        try:
            configs.append(training_args.config_from_run_args(
                {**a, "overrides": list(a["overrides"]) + [f"{k}={v}" for k, v in s.items()]}))
        except ValueError as err:
            raise ValueError(f"setting {', '.join(f'{k}={v}' for k, v in s.items())}: {err}") from None
    base = configs[0]
    env = envs.make(base.env.name, source=base.env.source, episode_length=base.episode_length,
                    physics=base.env.physics)
    structural = structural_fields(base, env, list(grid))
    batched = [f for f in grid if f not in structural]
    groups = {}
    for k, (s, cfg) in enumerate(zip(settings, configs)):
        groups.setdefault(tuple(s[f] for f in structural), []).append(k)
    out = []
    for key, members in groups.items():
        # A batched field must change nothing but itself (make_config derives some fields from others).
        first = configs[members[0]]
        same, apart = [members[0]], []
        for k in members[1:]:
            rebuilt = set_fields(first, {f: get_field(configs[k], f) for f in batched})
            (same if to_dict(rebuilt) == to_dict(configs[k]) else apart).append(k)
        for ks in [same] + [[k] for k in apart]:
            out.append({"settings": ks, "batched": batched if len(ks) > 1 else [],
                        "fixed": dict(zip(structural, key))})
    return settings, configs, out, env


def check_fits(a: dict, configs, groups, env) -> None:
    """Refuses (``ValueError``, one line: needed vs available) a sweep whose largest group's training state
    would not fit in memory; groups run one after another. From shapes alone: nothing compiles."""
    import jax

    from metapg_jax.seeds import vmap_seeds
    from metapg_jax.sweep import Sweep

    largest, label = 0, ""
    for g, group in enumerate(groups):
        cfg = configs[group["settings"][0]]
        sweep = Sweep(cfg, env, tuple(group["batched"]))
        n = len(group["settings"]) * a["seeds"]
        values = jax.ShapeDtypeStruct((n, len(group["batched"])), jax.numpy.float32)
        nbytes = memory.state_bytes(vmap_seeds(sweep.init), memory.abstract_keys(n), values)
        if nbytes > largest:
            largest, label = nbytes, (f"group {g + 1} ({len(group['settings'])} settings x {a['seeds']} seeds, "
                                      f"replay buffers of {cfg.buffer_capacity:,})")
    memory.check_fits(largest, f"the sweep's {label}")


def default_out(a: dict) -> str:
    student = "" if a["student"] == training_args.RUN_ARGS["student"] else f"-{a['student']}"
    return os.path.join("runs", f"sweep-{a['env']}-{a['method']}{student}-s{a['seed']}")


def prepare(args) -> tuple[dict, dict, str]:
    """(run args, grid, out) from the command line or, with --resume, from the stored sweep.json."""
    if args.resume:
        given = [k for k in sweep_args() if getattr(args, k) is not None] + (["grid"] if args.grid else [])
        if given:
            raise ValueError(f"--resume continues the stored sweep; do not give {', '.join('--' + k for k in given)}")
        path = os.path.join(args.resume, "sweep.json")
        if not os.path.exists(path):
            raise ValueError(f"--resume {args.resume}: no sweep.json there (not a sweep folder)")
        stored = json.load(open(path))
        return stored["run_args"], stored["grid"], args.resume
    a = training_args.run_args(argparse.Namespace(**{k: getattr(args, k) for k in sweep_args()}))
    # Stored resolved (never 'auto'), so a resume on another backend keeps the engine.
    a["physics"] = envs.resolve_physics(a["env"], a["source"], a["physics"])
    grid = parse_grid(args.grid)
    out = args.out or default_out(a)
    training_args.check_new_out(out, args.overwrite)
    return a, grid, out


def main(argv: list[str] | None = None) -> int:
    try:
        training_args.preload_plugins(argv)  # a plug-in's shortcut is then an option of the parser
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    args = build_parser().parse_args(argv)
    try:
        training_args.check_stop_options(0, args.checkpoint_minutes, args.term_grace)
        training_args.apply_physics_threads(args.physics_threads)
        a, grid, out = prepare(args)
        settings, configs, groups, env = plan(a, grid)
        check_fits(a, configs, groups, env)
        cache = compile_cache.resolve(args.compile_cache)
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    compile_cache.enable(cache)
    from metapg_jax.host import provenance, runfiles
    from metapg_jax.config import to_dict

    if not args.resume:
        if args.overwrite and os.path.exists(out):
            shutil.rmtree(out)
        os.makedirs(out, exist_ok=True)
        runfiles.write_json_atomic(os.path.join(out, "sweep.json"), {
            "run_args": a, "grid": grid,
            "settings": [{"setting": k, "values": s, "group": next(g for g, grp in enumerate(groups)
                                                                  if k in grp["settings"])}
                         for k, s in enumerate(settings)],
            "groups": groups, "config": to_dict(configs[0]), **provenance.record()})
    n = len(settings) * a["seeds"]
    label = training_args.run_label(configs[0])
    print(f"sweep of {len(settings)} settings x {a['seeds']} seeds = {n} runs of {label} "
          f"({configs[0].run.total_steps:,} env steps each) in {len(groups)} program(s); output {out}", flush=True)
    resume = resume_command(out)
    # A Ctrl-C between two groups' loops is kept (the next group stops after its first chunk, or none starts).
    with runner.Signals("the sweep stops at the next checkpoint or before the next group") as signals:
        try:
            for g, group in enumerate(groups):
                signals.check()
                if signals.requested:
                    print(f"\ninterrupted before group {g + 1} of {len(groups)} started; continue with: {resume}",
                          file=sys.stderr, flush=True)
                    return 130
                with signals.holding():
                    status = run_group(out, g, group, settings, configs, env, a, args,
                                       restart=runner.restart_command("experiments.sweep", argv))
                if status:
                    return status
            signals.check()
        except runner.Stopped as err:  # between two groups' loops
            print(f"\nstopped by {err.who} between two groups; continue with: {resume}", file=sys.stderr, flush=True)
            return err.status
    from experiments.analysis.render.sweeps import write_summary

    write_summary(out, settings, configs, plot=not args.no_plot)
    return 0


def resume_command(out: str) -> str:
    return f"python -m experiments.sweep --resume {out}"


def run_group(out: str, g: int, group: dict, settings, configs, env, a: dict, args, restart: str = "") -> int:
    """Trains one program group (resuming it from its checkpoint); returns the exit status. ``restart``:
    the command that starts the sweep again (printed if it is stopped before any checkpoint). The training driver's
    loop, recorder and loggers (``metapg_jax.host.driver``), around a program of settings x seeds of its own."""
    import jax
    import jax.numpy as jnp

    from metapg_jax.host import programs, runfiles
    from metapg_jax.host.checkpoint import Checkpointer
    from metapg_jax.host.driver import Recorder, checkpoint_due
    from metapg_jax.host.loggers import Loggers, ProgressBar
    from metapg_jax.seeds import seed_keys, vmap_seeds
    from metapg_jax.sweep import Sweep

    members, num_seeds = group["settings"], a["seeds"]
    cfg = configs[members[0]]
    checkpointer = Checkpointer(os.path.join(out, "groups", str(g), "checkpoints"))
    start = (checkpointer.steps() or [0])[-1]
    label = f"group {g + 1}: settings {', '.join(map(str, members))}" + (
        f" (batched: {', '.join(group['batched'])})" if group["batched"] else "")
    if start == cfg.num_chunks:
        print(f"{label}: done, skipped", flush=True)
        checkpointer.close()
        return 0
    resume = resume_command(out)

    def line(stop: runner.Stopped, in_flight: int | None, checkpointed: int | None) -> str | None:
        if checkpointed or g == 0:
            return None  # runner.stop_message's
        # The earlier groups are finished: --resume skips them and starts this one afresh.
        lost = (f"chunk {in_flight} of {cfg.num_chunks} of group {g + 1} was running and is lost"
                if in_flight is not None else f"group {g + 1} had started no chunk")
        return (f"stopped by {stop.who}{stop.reason}: {lost} (no checkpoint yet); groups 1-{g} are done; continue "
                f"with: {resume}")

    chunk_loop = runner.ChunkLoop(f"group {g + 1}", lambda: (checkpointer.steps() or [None])[-1], cfg.num_chunks,
                                  cfg.run.eval_every, resume, restart, line=line, grace=args.term_grace)
    with chunk_loop:  # a stop while compiling or in the loop: the stop line, chunk_loop.status
        chunk_loop.keep(checkpointer)
        sweep = Sweep(cfg, env, tuple(group["batched"]))
        values = jnp.repeat(sweep.values([configs[k] for k in members]), num_seeds, axis=0)  # setting-major
        keys = jnp.concatenate([seed_keys(a["seed"], num_seeds)] * len(members))
        t0 = time.perf_counter()
        # The group's programs are kept for the process (metapg_jax.host.programs): a sweep started again in it
        # (a resume, a notebook) traces nothing again.
        init_fn, _ = programs.kept(programs.key("sweep init", cfg, sweep.fields), lambda: jax.jit(vmap_seeds(sweep.init)))
        if start:
            state, _ = checkpointer.restore(jax.eval_shape(init_fn, keys, values))
            metrics_path = os.path.join(out, "metrics.jsonl")
            runfiles.truncate_jsonl(metrics_path, lambda r: r["setting"] not in members or r["chunk"] < start)
        else:
            state = init_fn(keys, values)
        chunk_fn, _ = programs.kept(programs.key("sweep chunk", cfg, sweep.fields, programs.shapes((state, values))),
                                    lambda: jax.jit(vmap_seeds(sweep.train_chunk), donate_argnums=0).lower(
                                        state, values).compile())
        print(f"{label}: {len(members)} x {num_seeds} runs, compiled in {time.perf_counter() - t0:.1f} s"
              + (f", resumed after {start} of {cfg.num_chunks} chunks" if start else ""), flush=True)
        bar = [] if args.quiet else [ProgressBar(f"group {g + 1}", runs=len(members) * num_seeds)]
        reports = chunk_loop.keep(Loggers(bar))
        reports.start(cfg, a, out, start)
        recorder = chunk_loop.keep(Recorder(out, reports, columns=setting_columns(members, num_seeds)))
        _, status, _ = chunk_loop.run(
            lambda s: chunk_fn(s, values), state, start=start, fetch=jax.device_get, record=recorder,
            save=lambda done, s: checkpointer.save(done, s, {"group": g, "settings": members}),
            due=checkpoint_due(0, args.checkpoint_minutes), interrupted=f" of group {g + 1}; continue with: {resume}")
        return status
    return chunk_loop.status


def setting_columns(members: list[int], num_seeds: int):
    """A group's ``Recorder`` columns: each row's setting and seed (rows are setting-major) and whether its
    parameters stayed finite through the chunk."""
    import numpy as np

    def columns(rows: list[dict], metrics) -> list[dict]:
        finite = np.asarray(metrics["cycle"]["finite"]).all(axis=1)
        for i, row in enumerate(rows):
            row["setting"], row["seed"], row["finite"] = members[i // num_seeds], i % num_seeds, bool(finite[i])
        return rows

    return columns


if __name__ == "__main__":
    sys.exit(main())
