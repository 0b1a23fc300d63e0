"""Train many seeds of a student (DDPG, TD3) with an explorer (noise, or Meta: the learned exploration
teacher) in one compiled program.

    python -m experiments.run --env=inverted_double_pendulum --seeds=8
    python -m experiments.run --env=pendulum --method=ddpg --noise=ou --steps=90000
    python -m experiments.run --env=hopper --student=td3 --method=meta --seeds=8 --physics=mujoco
    python -m experiments.run --env=pendulum --plugin my_explorer.py --method=uniform   # a registered explorer
    python -m experiments.run --env=hopper --preset=modern --set ddpg.actor_lr=1e-3
    python -m experiments.run --resume runs/hopper-meta-modern-s0
    python -m experiments.run --resume runs/hopper-meta-modern-s0 --steps=990000   # extend the budget
    python -m experiments.run --env=pendulum --wandb --wandb-project=my-project      # also to Weights & Biases

Writes under ``--out`` (default ``runs/<env>-<method>-<preset>-s<seed>``, ``...-<preset>-mujoco-s<seed>``
on MuJoCo's C engine, which ``--physics=auto``, the default, picks for a MuJoCo task on a CPU):
``config.json``, ``metrics.jsonl`` (one line per seed per evaluation, appended
as the run goes), ``cycles.jsonl`` (meta: per-cycle teacher metrics per seed),
``checkpoints/`` (the whole state, the last 2), ``learning_curve.png`` (mean ±
std band and per-seed lines), ``teacher.png`` (meta), ``visits.npz`` (sampled
states of the exploring policy and the student, early and late, per seed),
``policy.npz`` (the deterministic actors, see ``metapg_jax.load_policy``),
``summary.json``; and prints the final evaluation return per seed and mean ± std. With
``--tensorboard`` also ``tensorboard/seed_<i>/`` (the numbers of metrics.jsonl and cycles.jsonl as
TensorBoard scalars, one run per seed; ``tensorboard --logdir <out>/tensorboard``); with ``--wandb`` the same
numbers, the config and the summary go to Weights & Biases, one W&B run per seed in one group (their ids in
``wandb.json``). The training itself is ``metapg_jax.host.driver.run``'s; this command parses, checks and
chooses the loggers.

``--resume RUN_DIR --steps=N`` with N above the stored budget *extends* the run (finished or
not) to N env steps per seed: it continues from the latest checkpoint and ends where a run started
with ``--steps=N`` would, with the same numbers (nothing in training depends on the budget except
the replay capacity, min(1e6, budget), and a buffer that has never overwritten a transition grows
to the larger capacity unchanged; tested). Every other setting must stay the same; where the
default evaluation interval is derived from the budget (budgets under ten task intervals or not a
multiple of one), the stored interval is kept (the run then equals one started with ``--steps=N
--set run.eval_every=<stored>``). config.json
then holds the new budget and an ``extensions`` list; the shorter run's summary is kept as
``summary_<steps>.json``.

Exit status: 0 done; 2 bad input (one ``error:`` line, before anything
compiles); 3 non-finite parameters (the run stops, the last good checkpoint
stays); 130 interrupted by Ctrl-C (after finishing and checkpointing the chunk
in flight; ``--resume`` continues; a second Ctrl-C stops at once); 143 stopped by SIGTERM: after
finishing and checkpointing the chunk in flight where both fit in ``--term-grace`` seconds (default 25;
``--resume`` continues), else at once (the chunk in flight is lost, the last checkpoint stays). A run
stopped before its first checkpoint says so in one line, with the command that starts it again.
"""

from __future__ import annotations

import argparse
import os
import re
import sys

import envs
from metapg_jax import config as config_lib
from metapg_jax import strategy
from metapg_jax.host import compile_cache
from metapg_jax.host.processes import maybe_initialize_distributed
from metapg_jax.host.runner import TERM_GRACE, restart_command

from experiments.training.args import (RUN_ARGS, add_physics_threads_option, add_stop_options, apply_physics_threads,
                                       check_devices, check_new_out, check_stop_options, config_from_run_args, flags,
                                       preload_plugins, resolved_run_args, resume_args, run_args, run_label)
from experiments.training.finish import finalize
from experiments.training.memory import abstract_keys, check_fits, state_bytes


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m experiments.run",
        description="Train DDPG (baseline) or Meta (Algorithm 1 of Xu et al., 2018) on many seeds at once.")
    d = RUN_ARGS
    p.add_argument("--env", default=None,
                   help=f"task: {', '.join(envs.TASKS)} (default {d['env']}), or gym:<Id> for any gymnasium MuJoCo "
                        f"env on the C engine, e.g. gym:Walker2d-v5 or 'gym:Ant-v5(ctrl_cost_weight=0.1)' "
                        f"(docs/environments.md)")
    described = lambda specs: "; ".join(f"'{name}': {spec.summary}" for name, spec in specs.items())
    p.add_argument("--method", default=None,
                   help=f"the explorer (default {d['method']}): {described(strategy.explorers())}; or one a "
                        f"--plugin registers")
    for flag, (owners, field) in flags().items():  # a plug-in's too, once preload_plugins imported it
        p.add_argument(f"--{flag}", default=None,
                       help=f"--method={' or '.join(owners)} only: sets {field} (the same as --set {field}=V)")
    p.add_argument("--student", default=None,
                   help=f"the off-policy learner (default {d['student']}): {described(strategy.students())}; or "
                        f"one a --plugin registers")
    p.add_argument("--plugin", dest="plugins", action="append", default=None, metavar="MODULE|FILE.py",
                   help="import this module (dotted name) or Python file first: one that registers an explorer or "
                        "a student (metapg_jax.strategy.register_explorer, register_student), whose name "
                        "--method or --student then takes, and whose config group --set then sets; repeatable; "
                        "stored with the run, so --resume imports it again")
    p.add_argument("--preset", default=None,
                   help="'paper' (2018 baselines DDPG; default), 'modern' (256-256, 1 update/step) or 'tuned' "
                        "(the paper preset with the screen's Meta schedule)")
    p.add_argument("--seeds", type=int, default=None, help=f"number of seeds trained at once (default {d['seeds']})")
    p.add_argument("--seed", type=int, default=None,
                   help="base PRNG seed; seed i uses fold_in(PRNGKey(seed), i) (default 0)")
    p.add_argument("--steps", type=int, default=None,
                   help="stored env steps per seed (default: the paper's budget for the task)")
    p.add_argument("--source", default=None, help="MuJoCo models: 'gymnasium' (v5; default) or 'brax' (MJX only)")
    p.add_argument("--physics", default=None,
                   help="engine of the MuJoCo tasks: 'auto' (default: 'mujoco' where JAX runs on the CPU, "
                        "'mjx' on accelerators and for --source=brax), 'mjx' (JAX, float32; the one for "
                        "accelerators) or 'mujoco' (MuJoCo's C engine inside the program: float64, gymnasium's "
                        "numbers, several times faster on a CPU; runs on the host CPU). The resolved engine is "
                        "stored with the run; --resume keeps it")
    p.add_argument("--set", dest="overrides", action="append", default=None, metavar="GROUP.FIELD=VALUE",
                   help="override any config field, e.g. --set ddpg.tau=0.005 --set run.eval_every=3000 "
                        "(groups: env, run, ddpg, and each strategy's own: noise, meta, td3, a plug-in's; see "
                        "metapg_jax/config/ and metapg_jax/strategies/)")
    p.add_argument("--out", default=None, help="output folder (default runs/<env>-<method>-<preset>[-mujoco]-s<seed>)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output folder")
    p.add_argument("--resume", default=None, metavar="RUN_DIR",
                   help="continue the run in RUN_DIR from its latest checkpoint; options given with it must "
                        "match the stored run, except a larger --steps, which extends its budget")
    p.add_argument("--checkpoint-every", type=int, default=0, metavar="CHUNKS",
                   help="checkpoint every CHUNKS evaluation chunks; 0 (default) = whenever "
                        "--checkpoint-minutes have passed, and at the end")
    p.add_argument("--checkpoint-minutes", type=float, default=5.0,
                   help="with --checkpoint-every=0: minimum minutes between checkpoints (default 5)")
    add_stop_options(p)
    add_physics_threads_option(p)
    p.add_argument("--compile-cache", default=None, metavar="DIR|off",
                   help="keep compiled programs on disk for the next run or resume (default: "
                        "$JAX_COMPILATION_CACHE_DIR, else ~/.cache/metapg-jax/xla; 'off' compiles afresh; "
                        "see metapg_jax/host/compile_cache.py)")
    p.add_argument("--debug-nans", action="store_true", help="turn on jax_debug_nans (slow; for hunting NaNs)")
    p.add_argument("--no-plot", action="store_true", help="skip the PNG plots")
    p.add_argument("--tensorboard", action="store_true",
                   help="also write every number of metrics.jsonl (x: env steps) and, for meta, of cycles.jsonl "
                        "(as teacher/<name>, x: env steps at the end of the cycle) as TensorBoard scalars under "
                        "OUT/tensorboard/seed_<i>/, flushed per chunk; view with tensorboard --logdir "
                        "OUT/tensorboard. Needs the tensorboard extra (tensorboardX). Output only, not part of "
                        "the stored run: a --resume may add or leave it out; a resume with it first drops "
                        "events past the checkpoint and writes the finished rows the event files lack (all "
                        "of them if the run had no --tensorboard)")
    p.add_argument("--wandb", action="store_true",
                   help="also log the run to Weights & Biases, one W&B run per seed in one group (as CleanRL's "
                        "--track): its config, every number of metrics.jsonl and cycles.jsonl at env steps, the "
                        "final summary. Needs the wandb extra; WANDB_MODE=offline keeps it on disk. Output only: a "
                        "--resume with it continues the same W&B runs (ids in OUT/wandb.json) and logs what they lack")
    p.add_argument("--wandb-project", default=None, help="with --wandb: the W&B project (default metapg-jax)")
    p.add_argument("--wandb-entity", default=None, help="with --wandb: the W&B user or team (default: W&B's default)")
    p.add_argument("--wandb-group", default=None,
                   help="with --wandb: the W&B group of the seeds' runs (default: the output folder's name)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def prepare(args: argparse.Namespace) -> tuple[config_lib.Config, dict, str, bool, int | None]:
    """Everything that can fail on user input, before anything compiles: (config, run args, out, resume,
    the stored budget when the resume extends it, else None)."""
    extend_from = None
    check_stop_options(args.checkpoint_every, args.checkpoint_minutes, args.term_grace)
    apply_physics_threads(args.physics_threads)
    if args.tensorboard:
        from metapg_jax.host import tb_events

        tb_events.require_tensorboard()
    if not args.wandb and (args.wandb_project or args.wandb_entity or args.wandb_group):
        raise ValueError("--wandb-project, --wandb-entity and --wandb-group need --wandb")
    if args.wandb:
        from metapg_jax.host import wandb_runs

        wandb_runs.require_wandb()
    if args.resume:
        out = args.resume
        cfg, a, extend_from = resume_args(args, out)
    else:
        a = run_args(args)
        cfg = config_from_run_args(a)
        a = resolved_run_args(a, cfg)
        engine = "-mujoco" if cfg.env.physics == "mujoco" else ""
        student = "" if cfg.student == RUN_ARGS["student"] else f"-{cfg.student}"
        # A gym: task's name as a folder name: gym:Ant-v5(ctrl_cost_weight=0.1) -> gym-Ant-v5-ctrl_cost_weight=0.1.
        task = re.sub(r"[^\w.=+-]+", "-", cfg.env.name).strip("-")
        out = args.out or os.path.join("runs", f"{task}-{cfg.run.method}{student}-{cfg.preset}{engine}"
                                               f"-s{a['seed']}")
        check_new_out(out, args.overwrite)
    check_devices(a["seeds"])
    return cfg, a, out, bool(args.resume), extend_from


def main(argv: list[str] | None = None) -> int:
    try:
        preload_plugins(argv)  # a plug-in's shortcut is then an option of the parser
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    args = build_parser().parse_args(argv)
    try:
        maybe_initialize_distributed()
        cfg, a, out, resume, extend_from = prepare(args)
        cache = compile_cache.resolve(args.compile_cache)
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    compile_cache.enable(cache)
    from metapg_jax.host.driver import trainer_for
    from metapg_jax.train import vmap_seeds

    try:
        trainer = trainer_for(cfg)  # the config's, kept for the process with the programs the driver compiles
        check_fits(state_bytes(vmap_seeds(trainer.init), abstract_keys(a["seeds"])),
                   f"--seeds={a['seeds']} of {run_label(cfg)} with a replay buffer of {cfg.buffer_capacity:,}")
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if args.debug_nans:
        import jax

        jax.config.update("jax_debug_nans", True)
    wandb = {"project": args.wandb_project, "entity": args.wandb_entity, "group": args.wandb_group} \
        if args.wandb else None
    return run(cfg, a, out, trainer=trainer, resume=resume, overwrite=args.overwrite, plot=not args.no_plot,
               quiet=args.quiet, checkpoint_every=args.checkpoint_every, checkpoint_minutes=args.checkpoint_minutes,
               extend_from=extend_from, tensorboard=args.tensorboard, wandb=wandb,
               restart=restart_command("experiments.run", argv), term_grace=args.term_grace)


def run(cfg: config_lib.Config, a: dict, out: str, resume: bool = False, overwrite: bool = False,
        plot: bool = True, quiet: bool = False, checkpoint_every: int = 0, checkpoint_minutes: float = 5.0,
        extend_from: int | None = None, tensorboard: bool = False, wandb: dict | None = None,
        restart: str | None = None, trainer=None, term_grace: float = TERM_GRACE) -> int:
    """Trains the run (``prepare``'s outputs) with the command's loggers and files (``driver.run``); returns the exit
    status. ``wandb``: ``wandb_runs.WandB``'s options (None: no W&B); ``restart``: the command that starts it again
    (printed if it is stopped before its first checkpoint); ``trainer``: the config's (``make_train``), if built
    already; ``term_grace``: ``--term-grace``."""
    from metapg_jax.host import driver, loggers, tb_events, wandb_runs

    name = run_label(cfg)
    reports = [*([tb_events.TensorBoard()] if tensorboard else []), *([wandb_runs.WandB(**wandb)] if wandb else []),
               *([] if quiet else [loggers.ProgressBar(name)])]  # the bar last: its rates start after the others'

    def finish(state, record: dict) -> dict:
        return finalize(cfg, out, state, a["seeds"], plot=plot, extra=record)

    return driver.run(cfg, a, out, loggers=reports, resume=resume, extend_from=extend_from, overwrite=overwrite,
                      checkpoint_every=checkpoint_every, checkpoint_minutes=checkpoint_minutes, finalize=finish,
                      trainer=trainer, label=name, restart=restart, term_grace=term_grace)


if __name__ == "__main__":
    sys.exit(main())
