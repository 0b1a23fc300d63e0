"""Stored grid cells: reading run folders (``RunResult``, ``load_run``, ``collect``), the committed
archive of finished cells (``<results>/cells/<task>/<method>``: ``archive_cell``, ``copy_result_files``),
where a preset's artefacts go (``results_dir_for``, ``archive_dir_for``) and provenance (per cell, of
a build, the tables' footer).
"""

from __future__ import annotations

import dataclasses
import datetime
import gzip
import json
import os
from typing import Iterable

import numpy as np

from experiments.grid import methods as grid
from experiments.grid.methods import BASELINE, LEARNED_METHODS, META, METHODS, task_folder
from experiments.analysis.stats import final_returns
from metapg_jax.host import metric_rows, provenance, runfiles

# ---------------------------------------------------------------------------------------------- loading

# Per-chunk metrics about the data the explorer put in the buffer, kept next to the evaluation curves
# where a run logged them (behaviour.behaviour_rows): the return of the exploration episodes (DDPG's noisy
# or perturbed student; Meta's teacher collecting D0) and, for a teacher, its log-std, its distance to
# the student's action on D0 and the meta reward.
BEHAVIOUR_METRICS = ("train_return", "teacher_log_std", "teacher_student_distance", "meta_reward")

@dataclasses.dataclass
class RunResult:
    """One grid cell's stored results (a run folder, finished or not)."""

    task: str
    method: str
    path: str
    complete: bool            # summary.json exists (the run finished)
    config: dict              # config.json's "config"
    run_args: dict            # config.json's "run_args"
    info: dict                # the rest of config.json (jax version, backend, devices)
    summary: dict             # summary.json ({} while running)
    provenance: dict          # reproduce.json ({} for runs not started by experiments.reproduce)
    steps: np.ndarray         # (T,) env steps of the evaluations
    values: np.ndarray        # (seeds, T) evaluation returns
    train_seconds: float | None = None  # training time over all calls, from metrics.jsonl (metric_rows.training_seconds)
    train_seconds_exact: bool = False
    behaviour: dict = dataclasses.field(default_factory=dict)  # BEHAVIOUR_METRICS key -> (seeds, T), where logged

    @property
    def num_seeds(self) -> int:
        return int(self.values.shape[0])

    @property
    def budget(self) -> int:
        return int(self.config["run"]["total_steps"])

    @property
    def env_steps_done(self) -> int:
        return int(self.steps[-1]) if self.steps.size else 0

    def final(self) -> np.ndarray:
        return final_returns(self.values)


def load_run(path: str, task: str = "", method: str = "") -> RunResult | None:
    """A run folder's results, or None when it has no evaluations yet."""
    cfg_path, metrics_path = os.path.join(path, "config.json"), os.path.join(path, "metrics.jsonl")
    if not (os.path.exists(cfg_path) and os.path.exists(metrics_path)):
        return None
    with open(cfg_path) as f:
        stored = json.load(f)
    rows = runfiles.read_jsonl(metrics_path)
    if not rows:
        return None
    steps, values = metric_rows.curves(rows)
    behaviour = {k: np.asarray(metric_rows.curves(rows, k)[1], np.float64) for k in BEHAVIOUR_METRICS if k in rows[0]}
    train_s, exact = metric_rows.training_seconds(rows)
    summary = read_json(os.path.join(path, "summary.json"))
    info = {k: v for k, v in stored.items() if k not in ("config", "run_args")}
    return RunResult(task=task or stored["config"]["env"]["name"], method=method, path=path,
                     complete=bool(summary), config=stored["config"], run_args=stored["run_args"], info=info,
                     summary=summary, provenance=read_json(os.path.join(path, "reproduce.json")),
                     steps=np.asarray(steps), values=np.asarray(values, np.float64),
                     train_seconds=None if train_s is None else round(train_s, 2), train_seconds_exact=exact,
                     behaviour=behaviour)


def read_json(path: str) -> dict:
    """The JSON object stored at ``path``; {} when the file does not exist."""
    if not os.path.exists(path):
        return {}
    with open(path) as f:
        return json.load(f)


def collect(preset_dir: str, tasks: Iterable[str] | None = None, methods: Iterable[str] = METHODS,
            archive_dir: str | None = None) -> dict:
    """{(task, method): RunResult} for the cells of ``<preset_dir>/<task>/<method>`` that have evaluations
    (``tasks``: default the grid's, ``grid.tasks``).

    With ``archive_dir`` (the committed copies, see ``archive_cell``), a cell that has no finished run
    under ``preset_dir`` is read from ``<archive_dir>/<task>/<method>`` when a finished one is archived
    there: run folders are not committed, so a fresh clone has only the archive. (A ``gym:`` task's folder is
    ``grid.task_folder``'s name for it.)"""
    out = {}
    for task in grid.tasks() if tasks is None else tasks:
        for method in methods:
            r = load_run(os.path.join(preset_dir, task_folder(task), method), task, method)
            if archive_dir is not None and (r is None or not r.complete):
                a = load_run(os.path.join(archive_dir, task_folder(task), method), task, method)
                if a is not None and a.complete:
                    r = a
            if r is not None:
                out[(task, method)] = r
    return out


# ---------------------------------------------------------------------------------------------- archive

# What a finished cell keeps in the committed archive (``<results>/cells/<task>/<method>``): everything the
# artefacts read. Model checkpoints and the run's own PNGs stay in the run folder (gitignored).
ARCHIVE_FILES = ("config.json", "metrics.jsonl", "summary.json", "reproduce.json")
# A call started from a tree with uncommitted code changes stores them beside the cell (experiments.reproduce):
# uncommitted-<call>.diff, archived with it.
DIFF_PATTERN = "uncommitted-*.diff"
# visits.npz (the state-visitation sample) is kept for the two methods the figure compares, thinned to
# this many states per seed and array (evenly spaced; the figure draws <= 500 points per panel).
ARCHIVE_VISITS_PER_SEED = 250
# cycles.jsonl (a teacher's per-cycle metrics) is kept, gzipped, for the learned-exploration variants and controls
# (grid.LEARNED_METHODS): their diagnostics (experiments.analysis.learned) read it per cycle.
ARCHIVE_CYCLES = "cycles.jsonl.gz"


def results_dir_for(results_dir: str, preset: str) -> str:
    """The paper preset's artefacts go to ``results_dir``; another preset's to ``results_dir/<preset>``."""
    return results_dir if preset == "paper" else os.path.join(results_dir, preset)


def archive_dir_for(results_dir: str, preset: str) -> str:
    """The committed archive of ``preset``'s finished cells: ``<results_dir_for(...)>/cells``."""
    return os.path.join(results_dir_for(results_dir, preset), "cells")


def copy_result_files(run_path: str, archive_path: str) -> None:
    """Copies the ``ARCHIVE_FILES`` and stored diffs (``DIFF_PATTERN``) a run folder has into ``archive_path``,
    each atomically."""
    import glob
    import shutil

    os.makedirs(archive_path, exist_ok=True)
    diffs = sorted(os.path.basename(d) for d in glob.glob(os.path.join(run_path, DIFF_PATTERN)))
    for name in (*ARCHIVE_FILES, *diffs):
        src = os.path.join(run_path, name)
        if os.path.exists(src):
            tmp = os.path.join(archive_path, name + ".tmp")
            shutil.copyfile(src, tmp)
            os.replace(tmp, os.path.join(archive_path, name))


def thin_visits(visits: dict) -> dict:
    """A visitation sample thinned as the archive keeps it: at most ``ARCHIVE_VISITS_PER_SEED`` evenly spaced
    states per seed and array (the counts unchanged); an archived sample is returned as it is."""
    thinned = {}
    for k, x in visits.items():
        x = np.asarray(x)
        if x.ndim >= 2 and x.shape[-2] > ARCHIVE_VISITS_PER_SEED:  # (..., states, obs)
            idx = np.linspace(0, x.shape[-2] - 1, ARCHIVE_VISITS_PER_SEED).round().astype(int)
            x = np.take(x, idx, axis=-2)
        thinned[k] = x
    return thinned


def archive_cell(run_path: str, archive_path: str, method: str, baseline: str = BASELINE) -> bool:
    """Copies a finished run folder's results into the archive (atomically, file by file); False if the
    run is not finished. Re-archiving a cell replaces its files. The visitation sample is kept for the
    methods of the visitation figure only (Meta independent and ``baseline``), the per-cycle metrics for the
    learned-exploration methods only (``ARCHIVE_CYCLES``)."""
    if not os.path.exists(os.path.join(run_path, "summary.json")):
        return False
    copy_result_files(run_path, archive_path)
    cycles = os.path.join(run_path, "cycles.jsonl")
    if method in LEARNED_METHODS and os.path.exists(cycles):
        tmp = os.path.join(archive_path, ARCHIVE_CYCLES + ".tmp")
        with open(cycles, "rb") as src, open(tmp, "wb") as raw:
            with gzip.GzipFile(fileobj=raw, mode="wb", mtime=0, filename="") as out:  # the same bytes every time
                out.write(src.read())
        os.replace(tmp, os.path.join(archive_path, ARCHIVE_CYCLES))
    visits = os.path.join(run_path, "visits.npz")
    if method in (META, baseline) and os.path.exists(visits):
        with np.load(visits) as v:
            thinned = thin_visits(dict(v))
        runfiles.savez_atomic(os.path.join(archive_path, "visits.npz"), thinned)
    return True


# ---------------------------------------------------------------------------------------------- provenance

def stored_diffs(r: RunResult) -> list[str]:
    """The uncommitted changes stored beside a cell (``DIFF_PATTERN``), by file name."""
    import glob

    return sorted(os.path.basename(d) for d in glob.glob(os.path.join(r.path, DIFF_PATTERN)))


def cell_physics(r: RunResult) -> tuple[str, bool]:
    """(engine, recorded): the physics engine the cell's config names ('jax' for a JAX task, which has no MuJoCo
    model); a config without the field predates MuJoCo's C engine in this project, so its cell ran on MJX, the
    only engine then (recorded False)."""
    import envs  # brax on import: only when a cell's engine is asked for

    if not envs.has_mujoco(r.task):
        return "jax", True
    physics = r.config.get("env", {}).get("physics")
    return (physics, True) if physics else ("mjx", False)


def run_commits(r: RunResult) -> list[str]:
    """Every commit the cell's code ran at: its start (config.json), each recorded call (reproduce.json) and each
    budget extension (config.json's ``extensions``)."""
    found = [r.provenance.get("commit"), r.info.get("commit"), *(r.provenance.get("commits") or []),
             *(e.get("commit") for e in r.info.get("extensions", []))]
    return sorted({c for c in found if c and c != "unknown"})


def verification(r: RunResult) -> dict | None:
    """The cell's ``verified.json`` (``experiments.verify``: its first intervals re-run from a clean checkout
    of its commit), summarised; None where it was not checked."""
    v = read_json(os.path.join(r.path, "verified.json"))
    if not v:
        return None
    return {k: v.get(k) for k in ("verdict", "commit", "recorded_commit", "env_steps", "max_relative_difference")
            if k in v} | {"date": v.get("checked", {}).get("date")}


def is_dirty(r: RunResult) -> bool:
    """Whether the cell's code ran from a tree with uncommitted changes at any point: its start, a recorded call
    or a budget extension."""
    calls = r.provenance.get("calls") or []
    return bool(r.provenance.get("dirty") or r.info.get("dirty") or any(c.get("dirty") for c in calls)
                or any(e.get("dirty") for e in r.info.get("extensions", [])))


def cell_provenance(r: RunResult) -> dict:
    """What a result cell was made from: commit(s), whether a tree had uncommitted changes and the diffs stored
    for them, physics engine, config, seeds, budget, machine, wall time.

    ``wall_seconds`` is reproduce.json's (the recorded calls, compile included) or else the run's own
    summary; ``train_seconds_all_calls`` adds up the training time of every call from the metrics rows."""
    prov = r.provenance
    wall = prov.get("wall_seconds")
    if wall is None and r.summary:
        wall = (r.summary.get("compile_seconds") or 0) + (r.summary.get("train_seconds") or 0)
    physics, physics_recorded = cell_physics(r)
    return {
        "task": r.task, "method": r.method, "path": r.path, "complete": r.complete,
        "commit": prov.get("commit"), "commits": run_commits(r),
        "dirty": is_dirty(r), "diffs": stored_diffs(r), "verified": verification(r), "physics": physics,
        "physics_recorded": physics_recorded, "seeds": r.num_seeds, "base_seed": r.run_args.get("seed"),
        "budget_env_steps": r.budget, "env_steps_done": r.env_steps_done, "evaluations": int(r.steps.size),
        "preset": r.config.get("preset"), "run_args": r.run_args, "config": r.config,
        "machine": prov.get("machine") or {k: r.info.get(k) for k in ("jax_version", "backend", "devices")},
        "wall_seconds": wall,
        # every call's training time, compile excluded, from the metrics rows: also the calls a shutdown
        # killed before reproduce.json recorded them (which wall_seconds misses)
        "train_seconds_all_calls": r.train_seconds, "train_seconds_all_calls_exact": r.train_seconds_exact,
        # the process CPU time (user + system, all threads) of the recorded calls that measured it (reproduce.json;
        # only there for cells whose calls recorded it, so older manifests rebuild byte for byte)
        **({"cpu_seconds": prov["cpu_seconds"], "cpu_seconds_calls": prov.get("cpu_seconds_calls")}
           if prov.get("cpu_seconds") is not None else {}),
    }


def dirty_after_start(r: RunResult) -> bool:
    """Whether a call after the first (a resume) or a budget extension ran from a tree with uncommitted
    changes: code that a re-run of the first intervals (``experiments.verify``) does not cover."""
    calls = r.provenance.get("calls") or []
    return any(c.get("dirty") for c in calls[1:]) or any(e.get("dirty") for e in r.info.get("extensions", []))


def dirty_summary(cells: Iterable[RunResult]) -> str:
    """A sentence on the cells that ran from a tree with uncommitted changes: how many, which have no stored
    diff, what re-running those from a clean checkout of their commit found (``verification``) and which
    ran a later call or an extension from a dirty tree (not covered by that check); '' when none did."""
    cells = list(cells)
    dirty = [c for c in cells if is_dirty(c)]
    if not dirty:
        return ""
    undiffed = [c for c in dirty if not stored_diffs(c)]
    later = [c for c in undiffed if dirty_after_start(c)]
    checked = {c.path: verification(c) or {} for c in undiffed}  # each verified.json read once
    reproduced = [c for c in undiffed if checked[c.path].get("verdict") == "reproduced"]
    differs = [c for c in undiffed if checked[c.path].get("verdict") == "differs"]
    unchecked = [c for c in undiffed if not checked[c.path] and c not in later]
    names = lambda cs: ", ".join(f"{c.task}/{c.method}" for c in cs)
    text = (f"{len(dirty)} of {len(cells)} cells ran from a tree with uncommitted changes"
            + (f" ({len(undiffed)} without a stored diff: {names(undiffed)})" if undiffed else
               " (their diffs are stored beside them)") + ".")
    elsewhere = [c for c in reproduced if "recorded_commit" in checked[c.path]]
    whole = [c for c in reproduced if c.env_steps_done and checked[c.path].get("env_steps") == c.env_steps_done]
    if reproduced or differs:
        checked_cells = len(reproduced) + len(differs)
        span = ("over their first evaluation interval" if not whole else "over the whole run"
                if len(whole) == checked_cells else
                f"over their first evaluation interval, or the whole run for {len(whole)} ({names(whole)})")
        text += (f" Re-run from a clean checkout of the commit they started at, {span} "
                 f"(`experiments.verify`, `verified.json`): {len(reproduced)} reproduced the stored "
                 f"numbers" + (f" ({names(reproduced)})" if reproduced and (differs or later or unchecked) else "")
                 + (" (" + "; ".join(f"{c.task}/{c.method} at the later commit "
                                     f"`{checked[c.path]['commit'][:7]}`, which holds the changes it ran with"
                                     for c in elsewhere) + ")" if elsewhere else "")
                 + (f", {len(differs)} did not ({names(differs)})" if differs else "") + ".")
    if later:
        text += (f" {len(later)} ran a resumed call or a budget extension from a dirty tree, which such a re-run "
                 f"does not cover ({names(later)}).")
    if unchecked:
        text += f" Not checked: {names(unchecked)}."
    return text


def provenance_footer(build: dict, cells: Iterable[RunResult]) -> str:
    """Markdown lines: commit and machine of this build; every commit the runs used, the engines and
    ``dirty_summary``."""
    cells = list(cells)
    commits = sorted({commit for c in cells for commit in run_commits(c)} or {"unknown"})
    physics = {cell_physics(c) for c in cells}
    inferred = sorted({p for p, recorded in physics if not recorded})
    dirty = dirty_summary(cells)
    lines = ["", "---", "",
             f"Built {build['built']} from `{build['runs_dir']}` at commit `{build['commit'] or 'unknown'}`"
             f"{' (uncommitted changes)' if build.get('dirty') else ''} on {build['machine']['platform']} "
             f"({build['machine']['cpu_count']} CPUs). Runs used: {len(cells)}"
             + (f", made at commit(s) {', '.join(f'`{c}`' for c in commits)}" if cells else "")
             + (f"; engines: {', '.join(sorted({p for p, _ in physics}))}"
                + (f" ({', '.join(inferred)} inferred for cells whose config predates the physics option)"
                   if inferred else "") if cells else "")
             + "." + (f" {dirty}" if dirty else "")
             + " Per-cell commits, dirty flag, diffs, checks, engine, config, seeds, budget, machine and wall "
               "time: `manifest.json`."]
    return "\n".join(lines) + "\n"


def build_info(runs_dir: str) -> dict:
    """This build's provenance: local time, ``runs_dir``, commit, dirty flag and machine."""
    return {"built": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
            "runs_dir": runs_dir, **provenance.record()}
