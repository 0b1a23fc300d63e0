"""The training driver: a validated config, its run arguments and an output folder in; a run folder trained to its
budget out (new, resumed from its latest checkpoint, or extended to a larger budget), reported as it goes to
loggers (``metapg_jax.host.loggers``). ``experiments.run`` is its command line; the grid engine and notebooks call
``run`` directly, and ``experiments.sweep`` records its chunks with the same ``Recorder``.

The driver keeps the run's record, the files a resume and the summary depend on: ``config.json`` (with the
budget's extensions), ``metrics.jsonl`` and ``cycles.jsonl`` (cut back to the checkpoint on a resume, so that they
always end where the state does) and ``checkpoints/``. What a run shows or sends besides (the progress bar,
TensorBoard, Weights & Biases, a notebook's callback) is a logger: chosen per call, never stored with the run.
"""

from __future__ import annotations

import os
import shutil
import sys
import time
from typing import Any, Callable, Iterable, Sequence

from metapg_jax import config as config_lib
from metapg_jax.host import compile_cache, metric_rows, programs, runfiles
from metapg_jax.host.loggers import Logger, Loggers
from metapg_jax.host.processes import barrier, to_host
from metapg_jax.host.runner import TERM_GRACE, ChunkLoop, check_term_grace


def run(cfg: config_lib.Config, run_args: dict, out: str, *, loggers: Sequence[Logger] = (), resume: bool = False,
        extend_from: int | None = None, overwrite: bool = False, checkpoint_every: int = 0,
        checkpoint_minutes: float = 5.0, finalize: Callable[[Any, dict], dict] | None = None, trainer: Any = None,
        label: str | None = None, restart: str | None = None, term_grace: float = TERM_GRACE) -> int:
    """Trains the run in ``out`` to its budget; returns the exit status: 0 done, 3 non-finite parameters (the run
    stops before checkpointing that chunk; the last good checkpoint stays), 130 interrupted by a first Ctrl-C
    (after checkpointing the chunk in flight), 143 stopped by SIGTERM after checkpointing the chunk in flight
    within ``term_grace``, 130 / 143 stopped at once by a second Ctrl-C / a SIGTERM whose grace cannot be met
    (``runner.ChunkLoop``'s stop line says what was lost).

    Args:
      cfg: the validated config (``experiments.training.args.config_from_run_args``).
      run_args: the run arguments stored in ``config.json`` (``experiments.training.args.RUN_ARGS``, from which
        ``experiments.run --resume`` rebuilds the config); ``seeds`` and ``seed`` are read here.
      out: the run folder: new or empty (or replaced with ``overwrite``), or with ``resume`` the run's own.
      loggers: what the run reports to, on process 0 (``loggers.Logger``).
      resume: continue from the latest checkpoint in ``out``.
      extend_from: with ``resume``, the stored budget that ``cfg``'s larger one extends (recorded in config.json).
      checkpoint_every: checkpoint every this many chunks; 0: once ``checkpoint_minutes`` have passed since the
        last one. The last chunk is always checkpointed.
      finalize: ``(state, record) -> summary``, called on process 0 once the run has trained to its budget, with
        the final state (NumPy) and the driver's record of this call (compile and training seconds, throughput,
        memory); its summary goes to the loggers' ``finish`` (``experiments.training.finish.finalize`` writes
        summary.json, the policies, the visited states and the plots). None: the record goes there.
      trainer: ``metapg_jax.train.make_train(cfg)``, if built already.
      label: the run's name in its terminal lines (default '<env> <method>').
      restart: the command that starts the run again, printed if it is stopped before its first checkpoint
        (default: this call with ``overwrite=True``).
      term_grace: the seconds a SIGTERM leaves the run to finish its chunk in flight and checkpoint it before it exits
        143 (``runner.Signals``: if it cannot, it stops at once); 0: a SIGTERM stops it at once, as it always does in
        a job of several processes.
    """
    if checkpoint_every < 0 or not checkpoint_minutes > 0:
        raise ValueError(f"checkpoint_every must be >= 0 and checkpoint_minutes > 0, got {checkpoint_every} and "
                         f"{checkpoint_minutes}")
    check_term_grace(term_grace, "term_grace")
    if extend_from is not None and not resume:
        raise ValueError("extend_from extends a stored run: it needs resume=True")
    if not {"seeds", "seed"} <= run_args.keys():
        raise ValueError(f"run_args needs 'seeds' and 'seed' (experiments.training.args.RUN_ARGS), got "
                         f"{sorted(run_args)}")
    import jax

    from metapg_jax.host.checkpoint import saved_steps

    def checkpointed() -> int | None:
        done = saved_steps(os.path.join(out, "checkpoints"))
        return done[-1] if done else None

    if jax.process_count() > 1:
        # Each process would judge the grace on its own clock and signal time, and the checkpoint is written by
        # all of them together: one that finished its chunk while another stopped at once would wait for it for
        # ever. A job of several processes stops at once on SIGTERM (its last checkpoint stays).
        term_grace = 0.0
    resume_command = f"python -m experiments.run --resume {out}"
    chunk_loop = ChunkLoop("the run", checkpointed, cfg.num_chunks, cfg.run.eval_every, resume_command,
                           restart or "this call with overwrite=True", grace=term_grace)
    with chunk_loop:  # a stop while compiling or in the loop: the stop line, chunk_loop.status
        # Kept first, so closed last: after the files and the checkpointer, before a stop line.
        reports = chunk_loop.keep(Loggers(loggers if jax.process_index() == 0 else ()))
        return _train(chunk_loop, reports, cfg, run_args, out, resume=resume, extend_from=extend_from,
                      overwrite=overwrite, due=checkpoint_due(checkpoint_every, checkpoint_minutes),
                      finalize=finalize, trainer=trainer, label=label or f"{cfg.env.name} {cfg.run.method}",
                      resume_command=resume_command)
    return chunk_loop.status


def _train(chunk_loop: ChunkLoop, reports: Loggers, cfg: config_lib.Config, a: dict, out: str, *, resume: bool,
           extend_from: int | None, overwrite: bool, due: Callable[[int, float], bool],
           finalize: Callable[[Any, dict], dict] | None, trainer: Any, label: str, resume_command: str) -> int:
    import jax
    import numpy as np
    from jax.sharding import Mesh, NamedSharding, PartitionSpec

    from metapg_jax import replay
    from metapg_jax.host import provenance, terminal
    from metapg_jax.host.checkpoint import Checkpointer
    from metapg_jax.loop import checkpoint_shapes
    from metapg_jax.seeds import SEED_AXIS
    from metapg_jax.train import seed_keys, vmap_seeds

    num_seeds, seed = a["seeds"], a["seed"]
    main_process = jax.process_index() == 0
    if not resume:
        if overwrite and os.path.exists(out) and main_process:
            shutil.rmtree(out)
        os.makedirs(out, exist_ok=True)
        if main_process:
            runfiles.write_json_atomic(os.path.join(out, "config.json"), {
                "config": config_lib.to_dict(cfg), "run_args": a,
                "jax_version": jax.__version__, "backend": jax.default_backend(),
                "devices": [str(d) for d in jax.devices()], **provenance.record()})
    elif extend_from is not None and main_process:
        record_extension(out, cfg, a, extend_from)
    barrier("metapg-run-folder")  # process 0 has (re)made the folder before anyone writes into it

    # The config's own trainer (``trainer_for``) is kept with its programs for the process (``programs``): a second
    # run of the config in this process traces nothing again. Another trainer (a caller's) compiles its own.
    seeds_sharding = NamedSharding(Mesh(np.array(jax.devices()), (SEED_AXIS,)), PartitionSpec(SEED_AXIS))
    own = trainer is None or trainer is programs.peek(programs.key("trainer", cfg))
    trainer = trainer_for(cfg) if trainer is None else trainer
    t0 = time.perf_counter()

    def build_init():
        return jax.jit(vmap_seeds(trainer.init), out_shardings=seeds_sharding)

    init_fn = programs.kept(programs.key("init", cfg), build_init)[0] if own else build_init()
    keys = seed_keys(seed, num_seeds)
    print(f"{label} ({cfg.preset} preset, {cfg.env.source} source, {physics_label(cfg)} physics): {num_seeds} seeds x "
          f"{cfg.run.total_steps:,} env steps, {cfg.num_chunks} evaluations every {cfg.run.eval_every:,} steps "
          f"({cfg.cycles_per_chunk} cycles of {cfg.steps_per_cycle} steps) on {jax.device_count()} "
          f"{jax.default_backend()} device(s); output {out}", flush=True)

    cache, cache_before = compile_cache.current(), compile_cache.counts()
    checkpointer = chunk_loop.keep(Checkpointer(os.path.join(out, "checkpoints")))
    start = 0
    if resume:
        state, meta = checkpointer.restore(checkpoint_shapes(trainer, keys))
        if state.buffer.capacity != cfg.buffer_capacity:
            # Only min(1e6, budget) capacities grow, from a smaller budget below 1e6 that the buffer held
            # whole: no transition was overwritten (checked), so growing equals the longer run's buffer.
            if int(np.max(state.env_steps)) > state.buffer.capacity:
                raise RuntimeError(f"checkpoint in {out} holds a replay buffer that has overwritten transitions; "
                                   f"it cannot grow to {cfg.buffer_capacity:,}")
            state = state.replace(buffer=replay.grow(state.buffer, cfg.buffer_capacity))
        state = jax.device_put(state, seeds_sharding)
        start = int(meta["chunks_done"])
        first_cycle = start * cfg.cycles_per_chunk
        if main_process:  # the files are process 0's
            runfiles.truncate_jsonl(os.path.join(out, "metrics.jsonl"), lambda r: r["chunk"] < start)
            runfiles.truncate_jsonl(os.path.join(out, "cycles.jsonl"), lambda r: r["cycle"] < first_cycle)
        print(f"resumed after {start} of {cfg.num_chunks} chunks ({start * cfg.run.eval_every:,} env steps)",
              flush=True)
    else:
        state = init_fn(keys)

    def compile_chunk():
        return jax.jit(vmap_seeds(trainer.train_chunk), in_shardings=seeds_sharding, out_shardings=seeds_sharding,
                       donate_argnums=0).lower(state).compile()

    reused = False
    if own:
        chunk_fn, reused = programs.kept(programs.key("chunk", cfg, programs.shapes(state)), compile_chunk)
    else:
        chunk_fn = compile_chunk()
    compile_s = time.perf_counter() - t0
    buffer_mb = num_seeds * replay.nbytes(jax.tree.map(lambda x: x[0], state.buffer)) / 2**20
    cache_note, cache_record = compile_cache.describe(cache, cache_before, compile_cache.counts())
    if reused:
        cache_note, cache_record = f"the program compiled earlier in this process; {cache_note}", {
            **cache_record, "program_reused": True}
    print(f"compiled in {compile_s:.1f} s ({cache_note}); replay buffers {buffer_mb:,.0f} MiB", flush=True)

    reports.start(cfg, a, out, start)  # (a no-op on the other processes: their reports hold no logger)
    t_train = time.perf_counter()
    recorder = chunk_loop.keep(Recorder(out, reports, cfg.explorer_spec.cycle_metrics, cfg.cycles_per_chunk,
                                        started=t_train)) if main_process else None

    def record(chunk: int, metrics) -> int | None:
        bad = first_nonfinite(metrics, chunk, cfg)
        if bad is not None:
            seed_i, step = bad
            done = checkpointer.steps()
            print(f"\nerror: non-finite parameters in seed {seed_i} by env step {step:,} (chunk {chunk}); "
                  f"run stopped. Last good checkpoint: "
                  f"{f'after chunk {done[-1]}' if done else 'none'} in {checkpointer.directory}. "
                  f"Try --debug-nans or a smaller learning rate.", file=sys.stderr, flush=True)
            return 3
        if recorder is not None:
            recorder(chunk, metrics)
        return None

    def save(chunks_done: int, state) -> None:
        checkpointer.save(chunks_done, state, {"config": config_lib.to_dict(cfg), "run_args": a})
        reports.checkpoint(chunks_done)

    state, status, chunks_run = chunk_loop.run(chunk_fn, state, start=start, fetch=to_host, record=record, save=save,
                                               due=due, interrupted=f"; continue with: {resume_command}")
    if status:
        return status
    train_s = time.perf_counter() - t_train
    state = to_host(state)  # a collective with several processes: every process takes part
    if not main_process:
        return 0
    record = {
        "compile_seconds": round(compile_s, 2), **cache_record,
        "train_seconds": round(train_s, 2),
        "env_steps_per_second_total": round(num_seeds * chunks_run * cfg.run.eval_every / max(train_s, 1e-9), 1),
        "replay_mib": round(buffer_mb, 1), "peak_rss_mib": round(terminal.peak_rss_mib(), 1),
        "devices": jax.device_count(), "backend": jax.default_backend(), "resumed_from_chunk": start,
        **({"extended_from_steps": extend_from} if extend_from else {})}
    reports.finish(finalize(state, record) if finalize is not None else record)
    return 0


def trainer_for(cfg: config_lib.Config) -> Any:
    """``metapg_jax.train.make_train(cfg)``, kept for the process (``programs``): a driver run of ``cfg`` given this
    trainer (or none) reuses the programs an earlier run of ``cfg`` in this process compiled."""
    from metapg_jax.train import make_train

    return programs.kept(programs.key("trainer", cfg), lambda: make_train(cfg))[0]


class Recorder:
    """A chunk's record, as ``runner.run_chunks``' ``record``: its rows (``metric_rows.chunk_rows``, timed)
    appended to ``<out>/metrics.jsonl``, its explorer's cycle rows to ``<out>/cycles.jsonl``, then both handed to
    the loggers' ``chunk``. ``experiments.sweep`` records each program group's chunks with one.

    Args:
      out: the folder of the files.
      reports: the loggers (``loggers.Loggers``).
      cycle_metrics: the explorer's per-cycle metrics (``ExplorerSpec.cycle_metrics``); () writes no cycles.jsonl.
      cycles_per_chunk: the cycles of a chunk (numbers the cycle rows).
      columns: ``(rows, metrics) -> rows``: the caller's columns added to each chunk's rows before they are
        written (a sweep's setting, seed and finiteness).
      started: when training started (``time.perf_counter``; default: now): rows' ``wall_time`` counts from it.
    """

    def __init__(self, out: str, reports: Logger, cycle_metrics: Iterable[str] = (), cycles_per_chunk: int = 0,
                 columns: Callable[[list[dict], Any], list[dict]] | None = None, started: float | None = None):
        self._reports, self._columns = reports, columns
        self._cycle_metrics, self._cycles_per_chunk = tuple(cycle_metrics), cycles_per_chunk
        self._metrics = runfiles.JsonlWriter(os.path.join(out, "metrics.jsonl"))
        self._cycles = runfiles.JsonlWriter(os.path.join(out, "cycles.jsonl")) if self._cycle_metrics else None
        self.started = self._previous = time.perf_counter() if started is None else started

    def __call__(self, chunk: int, metrics: Any) -> None:
        now = time.perf_counter()
        rows = metric_rows.chunk_rows(metrics, chunk, now - self.started, now - self._previous)
        self._previous = now
        if self._columns is not None:
            rows = self._columns(rows, metrics)
        self._metrics.write(rows)
        cycles = []
        if self._cycles is not None:
            cycles = metric_rows.cycle_rows(metrics, self._cycle_metrics, chunk * self._cycles_per_chunk)
            self._cycles.write(cycles)
        self._reports.chunk(rows, cycles)

    def close(self) -> None:
        for writer in (self._metrics, self._cycles):
            if writer is not None:
                writer.close()


def checkpoint_due(every: int, minutes: float) -> Callable[[int, float], bool]:
    """``runner.run_chunks``' ``due``: every ``every`` chunks run in this call, or (``every`` 0) once ``minutes``
    have passed since the last checkpoint."""
    if every:
        return lambda chunks_run, since_save: chunks_run % every == 0
    return lambda chunks_run, since_save: since_save >= 60 * minutes


def first_nonfinite(metrics: Any, chunk: int, cfg: config_lib.Config) -> tuple[int, int] | None:
    """(seed, env step) of the first cycle of the chunk whose parameters are non-finite, or None."""
    import numpy as np

    finite = np.asarray(metrics["cycle"]["finite"])  # (seeds, cycles)
    if finite.all():
        return None
    cycles = np.where(~finite.all(0))[0]
    c = int(cycles[0])
    seed_i = int(np.where(~finite[:, c])[0][0])
    step = (chunk * cfg.cycles_per_chunk + c + 1) * cfg.steps_per_cycle
    return seed_i, step


def record_extension(out: str, cfg: config_lib.Config, a: dict, old_steps: int) -> None:
    """Before an extension runs: config.json gets the new budget (so a plain ``--resume`` continues the
    extension) and an ``extensions`` entry; the shorter run's summary is kept as ``summary_<steps>.json``."""
    import json

    from metapg_jax.host import provenance

    path = os.path.join(out, "config.json")
    with open(path) as f:
        stored = json.load(f)
    summary = os.path.join(out, "summary.json")
    if os.path.exists(summary):
        os.replace(summary, os.path.join(out, f"summary_{old_steps}.json"))
    entry = {"from_steps": old_steps, "to_steps": cfg.run.total_steps,
             "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"), **provenance.record()}
    runfiles.write_json_atomic(path, {**stored, "config": config_lib.to_dict(cfg), "run_args": a,
                                       "extensions": stored.get("extensions", []) + [entry]})


def physics_label(cfg: config_lib.Config) -> str:
    """The engine in the run's first line: 'JAX' (a JAX task), 'MuJoCo C' or 'MJX'."""
    import envs

    if not envs.has_mujoco(cfg.env.name):
        return "JAX"
    return "MuJoCo C" if cfg.env.physics == "mujoco" else "MJX"
