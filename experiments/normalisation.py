"""The anchors of the normalised scores (``experiments.analysis.stats.normalise``), per task: 0 = a uniformly random
policy's return, 1 = the reference return. Measured and written once; every aggregate reads them from the file.

    python -m experiments.normalisation                  # measures, writes results/normalisation.json
    python -m experiments.normalisation --episodes 20 --tasks pendulum,hopper --out /tmp/anchors.json
    python -m experiments.normalisation --tasks dmc:cartpole-swingup_sparse,dmc:reacher-hard \
        --out results/normalisation-dmc.json           # DeepMind Control tasks: 1 = the suite's maximum
    python -m experiments.normalisation --tasks mountain_car_continuous,dmc:hopper-hop \
        --out results/normalisation-hard.json          # 1 = each task's own fixed reference

* **0, the random policy**: actions uniform in [-1, 1]^d (the tasks' scaled action space) through the project's
  evaluation (``metapg_jax.evaluate`` with a stochastic policy: episodes from seeded resets, each up to the
  task's time limit), ``--episodes`` episodes per task, on the engine ``--physics=auto`` picks on this machine
  (MuJoCo's C engine for the MuJoCo tasks on a CPU; Pendulum is a JAX task). Mean and sample std over episodes.
* **1, the reference**: the mean final return of the paper's baseline, DDPG with adaptive parameter noise, at the
  paper's budget in the Table 2 grid (``results/table2.json``: 8 seeds, paper preset), with that cell's run
  commit. A fixed choice made before any aggregate was computed: no grid built later moves it, and the
  baseline of every comparison scores 1 on Table 2's tasks by construction (as human-normalised Atari scores
  put the human at 1).

  A task whose spec fixes its 1 (``envs.TaskSpec.reference_return``) has no cell in that grid: a DeepMind Control
  task's is the suite's own maximum, 1,000 (a reward of at most 1 per step over the 1,000-step episode), as the
  field normalises DMC returns; MountainCarContinuous's is gymnasium's solved threshold, 90. Their anchors go to a
  file of their own (``--out``), so that the Table 2 file keeps the tasks its aggregates were built on.
* **1 fixed by the task for Table 2's tasks too** (``--fixed-references``): gymnasium's solved threshold
  (InvertedPendulum 950, InvertedDoublePendulum 9,100, Hopper 3,800, HalfCheetah 4,800, Reacher -3.75) and
  Pendulum's maximum, 0 (Pendulum-v1 has no threshold): the dense set normalised the way the hard set is, by the
  random policy and the task's own 1 rather than a baseline's score, which most entries reach or pass on four of
  the six tasks (``results/normalisation-dense.json``)::

      python -m experiments.normalisation --fixed-references --out results/normalisation-dense.json
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEFAULT_OUT = os.path.join(ROOT, "results", "normalisation.json")
REFERENCE_GRID = os.path.join(ROOT, "results", "table2.json")
REFERENCE_METHOD = "ddpg-paramnoise"


def random_policy_returns(task: str, episodes: int, seed: int = 0):
    """(returns, lengths, engine) of ``episodes`` episodes of the uniformly random policy on ``task``."""
    import jax
    import numpy as np

    import envs
    from metapg_jax.config import make_config
    from metapg_jax.evaluate import evaluate

    cfg = make_config(task, "ddpg", physics="auto")
    env = envs.make(task, source=cfg.env.source, episode_length=cfg.episode_length, physics=cfg.env.physics)
    act = lambda obs, key: jax.random.uniform(key, (env.action_size,), minval=-1.0, maxval=1.0)
    ret, length = jax.jit(lambda k: evaluate(env, act, k, episodes, cfg.episode_length, stochastic=True))(
        jax.random.PRNGKey(seed))
    return np.asarray(ret, np.float64), np.asarray(length), cfg.env.physics


def fixed_reference(task: str, table2_tasks: bool = False) -> dict | None:
    """The reference a task's spec fixes (``envs.TaskSpec.reference_return``: a DeepMind Control task's maximum,
    MountainCarContinuous's solved threshold), or None for a task whose reference is a grid's cell: Table 2's
    tasks, unless ``table2_tasks`` (their solved thresholds, Pendulum's maximum)."""
    import envs

    spec = envs.get_spec(task)
    if spec.reference_return is None or (spec.table2 is not None and not table2_tasks):
        return None
    return {"reference_return": spec.reference_return, "reference": spec.reference}


def reference_returns(path: str = REFERENCE_GRID, method: str = REFERENCE_METHOD) -> dict:
    """Per task, the reference method's mean final return in the grid's JSON twin, with its provenance."""
    with open(path) as f:
        grid = json.load(f)
    out = {}
    for row in grid["rows"]:
        cell = row["methods"].get(method, {})
        if cell.get("status") == "done":
            out[row["task"]] = {"reference_return": cell["mean"], "reference_n": cell["n"],
                                "reference_budget": cell["budget"], "reference_run_commit": cell["run_commit"],
                                "reference_run_dir": cell["run_dir"]}
    return out


def describe_reference(path: str, tasks=None, name=str) -> str:
    """What a normalised score of 1 is in the anchors file at ``path``, for a page's text: Table 2's DDPG with
    parameter noise (``results/normalisation.json``), another grid's method, or each task's own fixed reference (the
    ``tasks``' ``reference`` texts with their returns, grouped; default: every task of the file; ``name(task)``
    names a task)."""
    with open(path) as f:
        doc = json.load(f)
    ref = doc.get("reference", {})
    if "grid" in ref:
        grid, method = ref["grid"], ref.get("method", REFERENCE_METHOD)
        if grid == "results/table2.json" and method == REFERENCE_METHOD:
            return "Table 2's DDPG with parameter noise at the paper's budget"
        return f"the mean final return of `{method}` in `{grid}`"
    groups: dict[tuple[str, float], list[str]] = {}
    for task in doc["tasks"] if tasks is None else tasks:
        a = doc["tasks"][task]
        groups.setdefault((a.get("reference", ref.get("kind", "the task's reference")), float(a["reference_return"])),
                          []).append(name(task))
    parts = [f"{text}, {value:,g} ({', '.join(names)})" for (text, value), names in groups.items()]
    return "each task's own fixed reference: " + "; ".join(parts)


def load(path: str = DEFAULT_OUT) -> dict[str, tuple[float, float]]:
    """task -> (low, high): the random policy's and the reference's returns from the anchors file."""
    with open(path) as f:
        tasks = json.load(f)["tasks"]
    anchors = {t: (float(a["random_return"]), float(a["reference_return"])) for t, a in tasks.items()}
    for t, (low, high) in anchors.items():
        if not high > low:
            raise ValueError(f"{t}: the reference return {high} is not above the random policy's {low}")
    return anchors


def main(argv: list[str] | None = None) -> int:
    import envs
    from envs import TASKS, paper_tasks

    # The default: the built-in tasks the reference grid (the paper's) has.
    grid_tasks = [t for t in TASKS if t in paper_tasks()]
    p = argparse.ArgumentParser(prog="python -m experiments.normalisation", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--tasks", default=",".join(grid_tasks),
                   help="comma-separated tasks (default: the paper's, those of the reference grid)")
    p.add_argument("--episodes", type=int, default=100, help="random-policy episodes per task (default 100)")
    p.add_argument("--seed", type=int, default=0, help="PRNG seed of the resets and actions (default 0)")
    p.add_argument("--out", default=DEFAULT_OUT, help="the anchors file (default results/normalisation.json)")
    p.add_argument("--fixed-references", action="store_true",
                   help="1 = each task's own fixed reference for Table 2's tasks too (gymnasium's solved thresholds, "
                        "Pendulum's maximum), not the reference grid's cell; into a file of its own (--out)")
    args = p.parse_args(argv)
    tasks = [t for t in args.tasks.split(",") if t]
    unknown = [t for t in tasks if t not in TASKS and not envs.is_dmc_task(t)]
    if unknown or not tasks:
        print(f"error: unknown task(s) {', '.join(unknown) or '(none given)'}; tasks: {', '.join(TASKS)}, "
              f"dmc:<domain>-<task>", file=sys.stderr)
        return 2
    try:
        for t in tasks:
            envs.get_spec(t)  # a dmc: task's name, and dm_control installed (one line)
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    fixed = {t: r for t in tasks if (r := fixed_reference(t, args.fixed_references)) is not None}
    if args.fixed_references and len(fixed) < len(tasks):
        print(f"error: no fixed reference for {', '.join(t for t in tasks if t not in fixed)}", file=sys.stderr)
        return 2
    if fixed and len(fixed) < len(tasks):
        print("error: DeepMind Control tasks and MountainCarContinuous have their own reference (the suite's maximum, "
              "the solved threshold) and file: pass them without the Table 2 tasks, with their own --out",
              file=sys.stderr)
        return 2
    if fixed and os.path.abspath(args.out) == os.path.abspath(DEFAULT_OUT):
        print(f"error: {DEFAULT_OUT} holds Table 2's anchors; write {', '.join(fixed)}'s to a file of their own "
              f"(--out results/normalisation-{'dense' if args.fixed_references else 'hard'}.json)", file=sys.stderr)
        return 2
    if args.episodes < 2:
        print(f"error: --episodes must be at least 2 (a mean and a std), got {args.episodes}", file=sys.stderr)
        return 2
    references = fixed or reference_returns()
    missing = [t for t in tasks if t not in references]
    if missing:
        print(f"error: {REFERENCE_GRID} has no finished {REFERENCE_METHOD} cell for {', '.join(missing)}",
              file=sys.stderr)
        return 2

    from metapg_jax.host.provenance import record as provenance
    from metapg_jax.host.runfiles import write_json_atomic

    anchors = {}
    for task in tasks:
        ret, length, engine = random_policy_returns(task, args.episodes, args.seed)
        anchors[task] = {"random_return": float(ret.mean()), "random_return_std": float(ret.std(ddof=1)),
                         "random_episode_length_mean": float(length.mean()), "engine": engine, **references[task]}
        print(f"{task}: random policy {ret.mean():.2f} ± {ret.std(ddof=1):.2f} over {args.episodes} episodes "
              f"({engine}); reference {references[task]['reference_return']:.2f}")
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    write_json_atomic(args.out, {
        "definition": "normalised score = (return - random_return) / (reference_return - random_return)",
        "random_policy": {"actions": "uniform in [-1, 1]^d, a fresh draw per step", "episodes": args.episodes,
                          "seed": args.seed, "statistics": "mean and sample std (ddof=1) over episodes"},
        "reference": ({"kind": "each task's own fixed reference (envs.TaskSpec.reference_return; the task's "
                               "'reference' says what it is)"}
                      if fixed else
                      {"grid": os.path.relpath(REFERENCE_GRID, ROOT), "method": REFERENCE_METHOD,
                       "statistic": "mean final return over the cell's seeds "
                                    "(experiments.analysis.stats.FINAL_DEFINITION)"}),
        "measured": {"date": datetime.date.today().isoformat(), **provenance()},
        "tasks": anchors})
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
