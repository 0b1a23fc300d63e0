"""What the training commands share before anything compiles: the run arguments (``RUN_ARGS``: what
``config.json`` stores so that ``--resume`` can rebuild and compare a run), their ``--plugin`` imports, the
validated config built from them, the checks of a resumed run, and the run's labels.

``experiments.run``, ``experiments.sweep`` and ``experiments.reproduce`` use them.
"""

from __future__ import annotations

import argparse
import json
import os
import sys

import envs
from metapg_jax import config as config_lib
from metapg_jax import strategy

# The built-in explorers' command-line shortcuts for one field of their group (``--teacher``, ``--noise``;
# metapg_jax.strategy.flags): {option: (explorers, dotted field)}. ``flags()`` adds an imported plug-in's.
FLAGS = strategy.flags()
# Arguments that define the run; stored in config.json so --resume can rebuild and compare it. The main job
# trains the paper's teacher: --method defaults to meta. ``defaults()`` adds an imported plug-in's shortcut.
RUN_ARGS = {"env": envs.DEFAULT_TASK, "method": "meta", **{flag: None for flag in FLAGS}, "preset": "paper",
            "seeds": 8, "seed": 0, "steps": None, "source": "gymnasium", "physics": "auto",
            "student": "ddpg", "overrides": [], "plugins": []}


def flags() -> dict[str, tuple[tuple[str, ...], str]]:
    """Every registered explorer's shortcut, a plug-in's too once ``import_plugins`` has imported it."""
    return strategy.flags()


def defaults() -> dict:
    """``RUN_ARGS`` and, after them, the shortcut of every plug-in imported so far (default None)."""
    return {**RUN_ARGS, **{flag: None for flag in flags() if flag not in RUN_ARGS}}


def preload_plugins(argv: list[str] | None) -> None:
    """Imports the plug-ins a command line names (``--plugin``, or a ``--resume``d run's stored ones) before its
    parser is built, so that a plug-in's shortcut is an option of it; raises ``ValueError`` (one line)."""
    pre = argparse.ArgumentParser(add_help=False)
    pre.add_argument("--plugin", dest="plugins", action="append", default=[])
    pre.add_argument("--resume", default=None)
    known, _ = pre.parse_known_args(sys.argv[1:] if argv is None else argv)
    names = list(known.plugins)
    path = os.path.join(known.resume, "config.json") if known.resume else None
    if path and os.path.exists(path):
        with open(path) as f:
            names += json.load(f).get("run_args", {}).get("plugins") or []
    import_plugins(names)


def parse_overrides(items: list[str]) -> dict[str, str]:
    out = {}
    for item in items:
        if "=" not in item:
            raise ValueError(f"--set expects GROUP.FIELD=VALUE, got {item!r}")
        k, v = item.split("=", 1)
        out[k.strip()] = v.strip()
    return out


def run_args(args: argparse.Namespace, stored: dict | None = None) -> dict:
    """The run-defining arguments: given ones, else the stored run's (on resume), else the defaults."""
    # (A stored run older than an argument has the argument's default.)
    known = defaults()
    base = dict(known if stored is None else {**known, **stored})
    for k in known:
        v = getattr(args, k, None)  # a command without the option (a sweep's shortcut of no plug-in)
        if v is not None:
            # --set on a resumed run adds to the stored overrides (and must not change anything).
            base[k] = list(base["overrides"]) + v if k == "overrides" else v
    return base


def import_plugins(names: list[str]) -> None:
    """Imports each ``--plugin`` (a dotted module name, or a path to a .py file) once per process."""
    import importlib
    import importlib.util

    for name in names:
        if name.endswith(".py"):
            path = os.path.abspath(name)
            module_name = "metapg_plugin_" + "".join(c if c.isalnum() else "_" for c in path)
            if module_name in sys.modules:
                continue
            if not os.path.isfile(path):
                raise ValueError(f"--plugin {name}: no such file")
            spec = importlib.util.spec_from_file_location(module_name, path)
            module = importlib.util.module_from_spec(spec)
            sys.modules[module_name] = module
            try:
                spec.loader.exec_module(module)
            except Exception as err:
                del sys.modules[module_name]
                raise ValueError(f"--plugin {name}: importing it failed: {type(err).__name__}: {err}") from None
        else:
            try:
                importlib.import_module(name)
            except ImportError as err:
                raise ValueError(f"--plugin {name}: cannot import it: {err}") from None


def add_stop_options(p: argparse.ArgumentParser, note: str = "") -> None:
    """Adds ``--term-grace`` (what a SIGTERM leaves a chunk loop; ``note``: the command's own words on it)."""
    from metapg_jax.host.runner import TERM_GRACE

    p.add_argument("--term-grace", type=float, default=TERM_GRACE, metavar="SECONDS",
                   help=f"on SIGTERM (what a batch scheduler sends before it kills): seconds to finish the chunk in "
                        f"flight, checkpoint it and exit 143 (if the chunk and its checkpoint cannot fit in them, it "
                        f"stops at once); 0: stop at once, losing the work since the last checkpoint{note} (default "
                        f"{TERM_GRACE:g}; docs/long-runs.md#schedulers)")


def check_stop_options(checkpoint_every: int, checkpoint_minutes: float, term_grace: float) -> None:
    """One-line ``ValueError`` for a bad checkpoint cadence or ``--term-grace``."""
    from metapg_jax.host.runner import check_term_grace

    if checkpoint_every < 0:
        raise ValueError(f"--checkpoint-every must be >= 0, got {checkpoint_every}")
    if not checkpoint_minutes > 0:
        raise ValueError(f"--checkpoint-minutes must be > 0, got {checkpoint_minutes:g}")
    check_term_grace(term_grace)


def add_physics_threads_option(p: argparse.ArgumentParser) -> None:
    """Adds ``--physics-threads`` (MuJoCo's C engine: the threads that step a batch's envs)."""
    p.add_argument("--physics-threads", default=None, metavar="N",
                   help="MuJoCo's C engine (--physics=mujoco, gym: tasks): threads that step the envs of a batch at "
                        "once (default: $METAPG_PHYSICS_THREADS, else the CPUs this process may use; one for a gym: "
                        "task). Changes no number, only the speed; not stored with the run "
                        "(docs/performance.md#physics-threads)")


def apply_physics_threads(value: str | None) -> None:
    """Checks ``--physics-threads`` (one-line ``ValueError``) and makes it the thread count of every C-engine env
    this process builds (``envs.host_call.THREADS_VARIABLE``); None leaves the default."""
    if value is None:
        return
    from envs.host_call import THREADS_VARIABLE, resolve_threads

    os.environ[THREADS_VARIABLE] = str(resolve_threads(value, "--physics-threads "))


def check_counts(seeds: int, seed: int, steps: int | None) -> None:
    """One-line ``ValueError`` for a non-positive seed count or budget, or a base seed outside [0, 2**32)."""
    if seeds <= 0:
        raise ValueError(f"--seeds must be positive, got {seeds}")
    if steps is not None and steps <= 0:
        raise ValueError(f"--steps must be positive, got {steps}")
    if not 0 <= seed < 2 ** 32:
        raise ValueError(f"--seed must be in [0, 2**32), got {seed}")


def config_from_run_args(a: dict) -> config_lib.Config:
    """Builds and validates the config; raises ValueError with one line on bad input. ``a["physics"]``
    may be 'auto' (make_config resolves it; ``resolved_run_args`` stores the engine it chose)."""
    import_plugins(a.get("plugins") or [])
    check_counts(a["seeds"], a["seed"], a["steps"])
    shortcuts = flags()
    for flag, (owners, _) in shortcuts.items():
        if a.get(flag) is not None and a["method"] not in owners:
            raise ValueError(f"--{flag} applies to --method={' or '.join(owners)} only")
    cfg = config_lib.make_config(env=a["env"], method=a["method"], preset=a["preset"], steps=a["steps"],
                                 source=a["source"], overrides=parse_overrides(a["overrides"]),
                                 physics=a["physics"], student=a["student"],
                                 **{flag: a.get(flag) for flag in shortcuts})
    return config_lib.validate(cfg)


def resolved_run_args(a: dict, cfg: config_lib.Config) -> dict:
    """The run args as stored: ``physics`` names the engine the config resolved (never 'auto'), so a
    resume on another backend keeps the engine the run started on."""
    return {**a, "physics": cfg.env.physics}


def run_label(cfg: config_lib.Config) -> str:
    """E.g. 'pendulum meta/independent' or 'hopper ddpg/adaptive-param (td3)': the explorer's label, and the
    student where it is not the default one."""
    label = cfg.explorer_spec.label
    detail = f"/{label(cfg)}" if label else ""
    student = "" if cfg.student == RUN_ARGS["student"] else f" ({cfg.student})"
    return f"{cfg.env.name} {cfg.run.method}{detail}{student}"


def check_devices(num_seeds: int) -> None:
    import jax

    n = jax.device_count()
    if num_seeds % n:
        raise ValueError(f"--seeds={num_seeds} is not a multiple of the {n} devices the seed axis is sharded over; "
                         f"use a multiple of {n} (or limit the devices, e.g. CUDA_VISIBLE_DEVICES)")


def check_new_out(out: str, overwrite: bool) -> None:
    """Refuses (``ValueError``, one line) an output folder that is a file, or that holds files unless
    ``--overwrite`` replaces them."""
    if os.path.exists(out) and not os.path.isdir(out):
        raise ValueError(f"--out {out} is a file, not a folder")
    if os.path.exists(out) and os.listdir(out) and not overwrite:
        raise ValueError(f"output folder {out} exists; pass --resume {out} to continue it, --overwrite to replace it, "
                         f"or --out elsewhere")


def resume_args(args: argparse.Namespace, out: str) -> tuple[config_lib.Config, dict, int | None]:
    """A resumed run's (config, run args, stored budget when the resume extends it, else None), from its
    ``config.json`` and the options given; raises ``ValueError`` (one line) when the options would change the
    stored run, when ``--steps`` shortens it, or when there is nothing to resume from."""
    extend_from = None
    path = os.path.join(out, "config.json")
    if not os.path.exists(path):
        raise ValueError(f"--resume {out}: no config.json there (not a run folder)")
    with open(path) as f:
        stored = json.load(f)
    if args.out is not None and os.path.abspath(args.out) != os.path.abspath(out):
        raise ValueError("--out and --resume name different folders; a resumed run writes into its own folder")
    # A run stored before --physics existed ran on its config's engine (MJX, the default then).
    stored_args = {"physics": stored["config"]["env"].get("physics", "mjx"), **stored["run_args"]}
    a = run_args(args, stored_args)
    cfg = config_from_run_args(a)
    a = resolved_run_args(a, cfg)
    old_steps, new_steps = stored["config"]["run"]["total_steps"], cfg.run.total_steps
    if new_steps != old_steps:
        if new_steps < old_steps:
            raise ValueError(f"--resume {out}: --steps={new_steps} is below the stored budget of {old_steps:,} "
                             f"env steps; a run can be extended, not shortened")
        extend_from = old_steps
        # Where the default evaluation interval is derived from the budget (config.make_config: budgets
        # under ten task intervals, or not a multiple of one), an extension keeps the stored interval.
        stored_every = stored["config"]["run"]["eval_every"]
        if cfg.run.eval_every != stored_every and "run.eval_every" not in parse_overrides(a["overrides"]):
            if new_steps % stored_every:
                raise ValueError(f"--resume {out}: the run's evaluation interval, {stored_every:,} env steps, "
                                 f"does not divide --steps={new_steps:,}; extend it to a multiple of "
                                 f"{stored_every:,} or start a new run")
            a = {**a, "overrides": list(a["overrides"]) + [f"run.eval_every={stored_every}"]}
            cfg = config_from_run_args(a)
            a = resolved_run_args(a, cfg)
    # An extension changes the budget only (experiments.run's docstring).
    # (Read back through from_dict: fields newer than the stored run compare as their defaults.)
    stored_cfg = config_lib.to_dict(config_lib.from_dict(stored["config"]))
    same_budget = {**stored_cfg, "run": {**stored_cfg["run"], "total_steps": new_steps}}
    differences = config_lib.diff(same_budget, config_lib.to_dict(cfg))
    differences += [f"{k} ({stored['run_args'][k]!r} -> {a[k]!r})" for k in ("seeds", "seed")
                    if stored["run_args"][k] != a[k]]
    if differences:
        what = f"extending it to {new_steps:,} steps would also change" if extend_from else \
            "the options given change the stored run"
        hint = " (pass the stored value with --set)" if extend_from else ""
        raise ValueError(f"--resume {out}: {what}: {'; '.join(differences)}{hint}")
    from metapg_jax.host.checkpoint import saved_steps

    if not saved_steps(os.path.join(out, "checkpoints")):
        raise ValueError(f"--resume {out}: no checkpoint under {out}/checkpoints; nothing to resume from")
    return cfg, a, extend_from
