"""Weights & Biases as a run's logger (``experiments.run --wandb``): one W&B run per seed, in one group, as CleanRL
logs one run per seed, so W&B's grouped charts show the seeds' mean and spread. wandb is imported here only, lazily:
it is an optional extra (``pip install -e ".[wandb]"``).
"""

from __future__ import annotations

import json
import os
from typing import Any

from metapg_jax.host import runfiles
from metapg_jax.host.loggers import Logger, finished_rows
from metapg_jax.host.metric_rows import scalars

DEFAULT_PROJECT = "metapg-jax"
# The oldest wandb with several runs open in one process (wandb.init(reinit="create_new")).
MIN_VERSION = "0.19.10"


def require_wandb() -> None:
    """Raises a one-line ``ValueError`` naming the extra if wandb (``MIN_VERSION`` or newer) cannot be imported:
    the ``--wandb`` check of the command line, before anything compiles."""
    try:
        import wandb
    except ImportError:
        raise ValueError('--wandb needs wandb: pip install -e ".[wandb]" (or pip install wandb)') from None
    from packaging.version import Version

    if Version(wandb.__version__) < Version(MIN_VERSION):
        raise ValueError(f'--wandb needs wandb {MIN_VERSION} or newer, found {wandb.__version__}: '
                         f'pip install -e ".[wandb]"')


class WandB(Logger):
    """A run's rows in W&B, one W&B run per seed: seed ``i``'s rows of ``metrics.jsonl`` (each numeric field under
    its own name) and ``cycles.jsonl`` (as ``<method>/<name>``, e.g. ``meta/meta_reward``) at W&B step = env steps
    (a cycle's: the env steps stored by the end of it), so every curve has env steps on its x axis, as
    TensorBoard's do. Each W&B run's config is the run's (``config.to_dict``), with ``run_args`` and
    ``seed_index``; its summary gets the finished run's numbers (the seed's own where the summary has one per seed:
    ``final_return_per_seed`` -> ``final_return``).

    The W&B runs' ids are kept in ``<out>/wandb.json`` with the chunks logged so far: a resume continues the same
    W&B runs (``resume="allow"``), logs the finished chunks they lack (all of them for a run started without
    ``--wandb``) and skips the chunks it trains again that W&B has already (a resume repeats them bit for bit). The
    options given on a resume replace the stored ones; the ones not given are the stored ones. W&B's own settings
    (``WANDB_MODE=offline``, ``WANDB_DIR``, ``WANDB_API_KEY``, ...) come from its environment variables.

    Args:
      project: the W&B project (default ``DEFAULT_PROJECT``).
      entity: the W&B user or team (default: W&B's default entity).
      group: the W&B group of the seeds' runs (default: the run folder's name, so that each run's seeds form one
        group; give several runs one group to put all their seeds together).
    """

    def __init__(self, project: str | None = None, entity: str | None = None, group: str | None = None):
        self._given = {"project": project, "entity": entity, "group": group}
        self._runs: list[Any] = []
        self._path, self._stored, self._logged, self._finished = "", {}, 0, False
        self._prefix, self._steps_per_cycle, self._cycles_per_chunk = "", 0, 0

    def start(self, cfg: Any, run_args: dict, out: str, resumed_from: int) -> None:
        import wandb

        from metapg_jax.config import to_dict

        self._path = os.path.join(out, "wandb.json")
        stored = {}
        if os.path.exists(self._path):
            with open(self._path) as f:
                stored = json.load(f)
        folder = os.path.basename(os.path.abspath(out))
        where = {k: self._given[k] or stored.get(k) for k in self._given}
        where = {**where, "project": where["project"] or DEFAULT_PROJECT, "group": where["group"] or folder}
        if any(stored.get(k) != where[k] for k in ("project", "entity")):  # new W&B runs, in another project
            stored = {}
        ids = stored.get("runs") or [None] * run_args["seeds"]
        self._logged = stored.get("logged_chunks", 0)
        self._prefix = f"{cfg.run.method}/"
        self._steps_per_cycle, self._cycles_per_chunk = cfg.steps_per_cycle, cfg.cycles_per_chunk
        config = {**to_dict(cfg), "run_args": run_args}
        for i, run_id in enumerate(ids):
            self._runs.append(wandb.init(
                **where, id=run_id, name=f"{folder}-seed{i}", config={**config, "seed_index": i}, resume="allow",
                reinit="create_new", settings=wandb.Settings(console="off", silent=True)))
        self._stored = {**where, "runs": [r.id for r in self._runs]}
        self._save()
        run = self._runs[0]
        print(f"W&B: {len(self._runs)} runs, one per seed, in project {where['project']}, group {where['group']}"
              + (f", offline in {os.path.dirname(os.path.dirname(run.dir))} (wandb sync uploads them)" if run.offline
                 else f" ({run.project_url})"), flush=True)
        if resumed_from > self._logged:
            rows, cycles = finished_rows(out)
            self._log([r for r in rows if r["chunk"] < resumed_from], cycles)
            self._logged = resumed_from
            self._save()

    def chunk(self, rows: list[dict], cycles: list[dict]) -> None:
        self._log(rows, cycles)
        self._logged = max(self._logged, int(rows[0]["chunk"]) + 1)
        self._save()

    def finish(self, summary: dict) -> None:
        for i, run in enumerate(self._runs):
            for k, v in summary.items():
                if k.endswith("_per_seed") and isinstance(v, list) and len(v) == len(self._runs):
                    run.summary[k[:-len("_per_seed")]] = v[i]
                elif isinstance(v, (int, float, str)) and not k.endswith("_per_seed"):
                    run.summary[k] = v
        self._finished = True

    def close(self) -> None:
        for run in self._runs:  # a run stopped before its budget is marked failed; a resume continues it
            run.finish(exit_code=0 if self._finished else 1)
        self._runs = []

    def _log(self, rows: list[dict], cycles: list[dict]) -> None:
        """Logs the rows of chunks W&B lacks (from ``logged_chunks`` on), per seed in env-step order; a chunk's
        last cycle and its evaluation share a step."""
        first_cycle = self._logged * self._cycles_per_chunk
        steps: dict[int, dict[int, dict]] = {}  # seed -> env steps -> {metric: value}
        for c in cycles:
            if c["cycle"] >= first_cycle:
                step = (int(c["cycle"]) + 1) * self._steps_per_cycle
                steps.setdefault(int(c["seed"]), {}).setdefault(step, {}).update(
                    {self._prefix + k: v for k, v in scalars(c).items()})
        for r in rows:
            if r["chunk"] >= self._logged:
                steps.setdefault(int(r["seed"]), {}).setdefault(int(r["env_steps"]), {}).update(scalars(r))
        for seed, by_step in steps.items():
            for step in sorted(by_step):
                self._runs[seed].log(by_step[step], step=step, commit=True)

    def _save(self) -> None:
        runfiles.write_json_atomic(self._path, {**self._stored, "logged_chunks": self._logged})
