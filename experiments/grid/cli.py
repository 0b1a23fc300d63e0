"""The command-line options every grid command shares (``experiments.reproduce``, ``experiments.screen``,
``experiments.benchmark``): the cells' common run (seeds, base seed, budget, engine, overrides), where the grid
keeps them, how each cell runs, and the launcher; their checks, and the typed data they become
(``GridSpec``, ``GridRun``); and the launch of a list of cells, here or on Ray."""

from __future__ import annotations

import argparse

from experiments.grid.spec import GridRun, GridSpec


def add_grid_options(p: argparse.ArgumentParser, *, seeds: int, seed: int, steps: int | None, physics: str,
                     steps_help: str, physics_help: str, runs_help: str, results_help: str) -> None:
    """Adds the shared options with the command's defaults (``runs_dir``/``results_dir`` default to None: each
    command derives its folders)."""
    from experiments.training import args as training_args

    p.add_argument("--seeds", type=int, default=seeds, help=f"seeds per cell (default {seeds})")
    p.add_argument("--seed", type=int, default=seed, help=f"base PRNG seed of every cell (default {seed})")
    p.add_argument("--steps", type=int, default=steps, help=steps_help)
    p.add_argument("--physics", default=physics, choices=("mjx", "mujoco"), help=physics_help)
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="GROUP.FIELD=VALUE",
                   help="config override passed to every cell's experiments.run (e.g. tiny test settings)")
    p.add_argument("--runs-dir", default=None, help=runs_help)
    p.add_argument("--results-dir", default=None, help=results_help)
    p.add_argument("--no-plot", action="store_true", help="skip each run's own PNGs (the artefacts are still drawn)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument("--tensorboard", action="store_true",
                   help="each cell also writes TensorBoard scalars to <cell>/tensorboard/seed_<i>/ (experiments.run "
                        "--tensorboard; needs the tensorboard extra, tensorboardX)")
    p.add_argument("--checkpoint-every", type=int, default=0, metavar="CHUNKS",
                   help="each cell checkpoints every CHUNKS chunks (experiments.run --checkpoint-every; default 0: "
                        "every --checkpoint-minutes)")
    p.add_argument("--checkpoint-minutes", type=float, default=5.0,
                   help="each cell's minimum minutes between checkpoints (experiments.run; default 5)")
    training_args.add_stop_options(p, "; passed to each cell's experiments.run; a grid stopped by SIGTERM exits 143 "
                                      "without building its report, and the same command resumes the cell")
    training_args.add_physics_threads_option(p)
    p.add_argument("--launcher", default="local", choices=("local", "ray"),
                   help="local (default): the cells one after another in this process; ray: each cell a Ray task "
                        "(the ray extra), on a local Ray instance started here, or on --ray-address")
    p.add_argument("--ray-address", default=None, metavar="HOST:PORT|auto",
                   help="an existing Ray cluster (default: start a local instance); its nodes need this package "
                        "installed and --runs-dir/--results-dir on a shared file system")
    p.add_argument("--ray-cpus-per-cell", type=float, default=1.0, help="CPUs each cell's task asks Ray for (default 1)")
    p.add_argument("--ray-gpus-per-cell", type=float, default=0.0, help="GPUs each cell's task asks Ray for (default 0)")
    p.add_argument("--ray-retries", type=int, default=3,
                   help="times Ray restarts a cell whose worker died (it resumes from its last checkpoint; default 3)")


def check_grid_options(a: argparse.Namespace, trains: bool) -> None:
    """``ValueError`` (one line) for a bad shared option; ``trains``: the command will run cells (not a dry run or a
    report), so the launcher's and TensorBoard's packages must be there."""
    from experiments.training import args as training_args

    training_args.check_counts(a.seeds, a.seed, a.steps)
    training_args.parse_overrides(a.overrides)  # GROUP.FIELD=VALUE each
    if a.ray_cpus_per_cell < 0 or a.ray_gpus_per_cell < 0 or a.ray_retries < 0:
        raise ValueError("--ray-cpus-per-cell, --ray-gpus-per-cell and --ray-retries must be >= 0")
    training_args.check_stop_options(a.checkpoint_every, a.checkpoint_minutes, a.term_grace)
    training_args.apply_physics_threads(a.physics_threads)
    if trains and a.launcher == "ray":
        try:
            import ray  # noqa: F401
        except ImportError:
            raise ValueError("--launcher ray needs Ray: pip install -e \".[ray]\"") from None
    if trains and a.tensorboard:
        from metapg_jax.host import tb_events

        tb_events.require_tensorboard()


def grid_spec(a: argparse.Namespace, preset: str, student: str = "ddpg", source: str = "gymnasium") -> GridSpec:
    """What the options make every cell's run share."""
    return GridSpec(preset=preset, student=student, seeds=a.seeds, seed=a.seed, steps=a.steps, source=source,
                    physics=a.physics, overrides=tuple(a.overrides))


def grid_run(a: argparse.Namespace, runs_dir: str, results_dir: str, preset: str, baseline: str,
             no_plot: bool | None = None) -> GridRun:
    """Where the options keep the grid's cells and how they run them (``no_plot``: the command's own choice,
    else ``--no-plot``)."""
    return GridRun(runs_dir, results_dir, preset=preset, baseline=baseline, quiet=a.quiet,
                   no_plot=a.no_plot if no_plot is None else no_plot, tensorboard=a.tensorboard,
                   checkpoint_every=a.checkpoint_every, checkpoint_minutes=a.checkpoint_minutes,
                   term_grace=a.term_grace)


def launch(cells: list, a: argparse.Namespace, word: str = "grid") -> tuple[int, dict]:
    """Runs the cells here one after another or, with ``--launcher ray`` (and no ``--dry-run``), as Ray tasks, and
    prints one line that counts what happened to them; returns (exit status, {cell key: what happened})."""
    from experiments.training import grid_cells

    if a.launcher == "ray" and not a.dry_run:
        status, report = grid_cells.run_cells_ray(cells, a)
    else:
        status, report = grid_cells.run_cells(cells, dry_run=a.dry_run)
    counts = {}
    for v in report.values():
        counts[v] = counts.get(v, 0) + 1
    print(f"{word}: " + (", ".join(f"{n} {k}" for k, n in sorted(counts.items())) or "nothing to do"), flush=True)
    return status, report
