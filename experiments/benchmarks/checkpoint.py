"""What a checkpoint costs and what a SIGTERM loses (``python -m experiments.bench --checkpoint``,
``--checkpoint-sigterm``), and their tables.

``measure_checkpoint``: the seconds and bytes of the checkpoint a run writes (``Checkpointer.save``, as the training
driver calls it: the whole seed-batched state and its metadata, atomic, the oldest of three deleted) for a run's
command line, built as ``experiments.run`` builds it; the median of a few writes, once with the replay buffers as a
new run holds them (empty) and once full, every row holding random values (the most a checkpoint holds, and the least
compressible: orbax compresses what it writes, so an empty buffer costs next to nothing).

``measure_sigterm``: the README's main job in a fresh process, sent SIGTERM a second into a chunk (after a few
chunks and before its first checkpoint, as in a preempted run's first minutes), with a ``--term-grace``: when it
exited, with which status, what its checkpoint holds and how many seconds of training it lost.
"""

from __future__ import annotations

import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time

from experiments.benchmarks.main_job import MAIN_JOB

# The runs whose checkpoints are measured: the README's main job, and a 10-seed cell of the modern preset (the
# largest state of the stored grids: Hopper's 11 observations, 10 x 1M replay rows).
CASES = {"main job": MAIN_JOB, "modern cell": ["--env=hopper", "--preset=modern", "--seeds=10"]}
MARKDOWN = "results/measurements/checkpoint-cost.md"  # where the tables go by default (from the repository root)


def full_buffers(state, seed: int = 0):
    """``state`` with every replay row written: random normal values in every field (floats stored at full
    entropy compress the least), the buffers marked full."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    rng = np.random.default_rng(seed)
    buffer = state.buffer
    data = jax.tree.map(lambda x: jnp.asarray(rng.standard_normal(x.shape, dtype=np.float32).astype(x.dtype)),
                        buffer.data)
    return state.replace(buffer=buffer.replace(data=data, ptr=jnp.zeros_like(buffer.ptr),
                                               size=jnp.full_like(buffer.size, buffer.capacity)))


def folder_bytes(path: str) -> int:
    return sum(os.path.getsize(os.path.join(root, f)) for root, _, files in os.walk(path) for f in files)


def measure_checkpoint(label: str, argv: list[str], writes: int = 3) -> dict:
    """Checkpoint seconds and bytes (median of ``writes``) of the run ``experiments.run ARGV`` would train, with its
    replay buffers empty and full; the state's bytes in memory beside them."""
    import jax

    from experiments import run
    from metapg_jax import config as config_lib
    from metapg_jax.host.checkpoint import Checkpointer
    from metapg_jax.train import make_train, seed_keys, vmap_seeds

    with tempfile.TemporaryDirectory(prefix="metapg-checkpoint-cost-") as tmp:
        cfg, a, _, _, _ = run.prepare(run.build_parser().parse_args([*argv, "--out", os.path.join(tmp, "run")]))
        trainer = make_train(cfg)
        state = jax.jit(vmap_seeds(trainer.init))(seed_keys(a["seed"], a["seeds"]))
        meta = {"config": config_lib.to_dict(cfg), "run_args": a}
        row = {"case": label, "argv": argv, "seeds": a["seeds"], "env": cfg.env.name, "preset": cfg.preset,
               "physics": cfg.env.physics, "buffer_capacity": cfg.buffer_capacity, "writes": writes,
               "state_bytes": sum(x.nbytes for x in jax.tree.leaves(state))}
        for fill in ("empty", "full"):
            if fill == "full":
                state = jax.block_until_ready(full_buffers(state))
            checkpointer = Checkpointer(os.path.join(tmp, fill))
            seconds, sizes = [], []
            for i in range(1, writes + 1):
                t = time.perf_counter()
                checkpointer.save(i, state, meta)
                seconds.append(time.perf_counter() - t)
                sizes.append(folder_bytes(os.path.join(checkpointer.directory, str(i))))
            checkpointer.close()
            row[fill] = {"seconds": [round(s, 3) for s in seconds], "median_s": round(statistics.median(seconds), 3),
                         "bytes": int(statistics.median(sizes))}
        del state
    return row


def measure_sigterm(grace: float, steps: int, after_chunks: int, delay: float, cache: str) -> dict:
    """The main job (``MAIN_JOB``, ``--steps``) in a fresh process with ``--term-grace=grace``, sent SIGTERM ``delay``
    seconds after its ``after_chunks``-th chunk is recorded. ``lost_s``: the training before the signal that no
    checkpoint holds (the recorded chunks after the checkpoint's, and the part of the chunk in flight before the
    signal unless the checkpoint holds that chunk); ``exit_after_s``: signal to exit."""
    from metapg_jax.host.checkpoint import saved_steps

    with tempfile.TemporaryDirectory(prefix="metapg-sigterm-") as tmp:
        out = os.path.join(tmp, "run")
        argv = [sys.executable, "-m", "experiments.run", *MAIN_JOB, f"--steps={steps}", f"--term-grace={grace:g}",
                f"--compile-cache={cache}", "--quiet", "--no-plot", f"--out={out}"]
        proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        metrics, rows, seen = os.path.join(out, "metrics.jsonl"), [], None
        while proc.poll() is None:
            if os.path.exists(metrics):
                with open(metrics) as f:
                    rows = [json.loads(line) for line in f if line.endswith("\n")]
                if len({r["chunk"] for r in rows}) >= after_chunks:
                    seen = time.perf_counter()
                    break
            time.sleep(0.02)
        if seen is None:
            raise RuntimeError(f"the main job ended before {after_chunks} chunks: {proc.stderr.read()[-2000:]}")
        time.sleep(max(seen + delay - time.perf_counter(), 0.0))
        sent = time.perf_counter()
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=600)
        exited = time.perf_counter()
        done = saved_steps(os.path.join(out, "checkpoints"))
    checkpointed = done[-1] if done else 0
    chunk_s = {r["chunk"]: r["chunk_seconds"] for r in rows}
    lost = sum(s for c, s in chunk_s.items() if c >= checkpointed) + (sent - seen if checkpointed <= after_chunks
                                                                      else 0.0)
    return {"grace_s": grace, "status": proc.returncode, "chunks_before_signal": after_chunks,
            "signal_into_chunk_s": round(sent - seen, 2), "chunk_s": round(statistics.median(chunk_s.values()), 1),
            "checkpointed_chunks": checkpointed, "exit_after_s": round(exited - sent, 1), "lost_s": round(lost, 1),
            "last_line": err.strip().splitlines()[-1] if err.strip() else ""}


def _mib(n: int) -> str:
    return f"{n / 2**20:,.1f}"


def checkpoint_markdown(rows: list[dict], meta: dict, grace: float) -> str:
    """The checkpoint-cost table and its verdict against the default grace ``grace``."""
    lines = [f"## What a checkpoint costs ({meta['date']}, commit {meta['commit'][:7]}"
             f"{' (uncommitted changes)' if meta.get('dirty') else ''})", "",
             f"`python -m experiments.bench --checkpoint`: {meta['machine']}, JAX {meta['jax']}, {meta['backend']}; "
             f"{meta['conditions']}. Each run's state as `experiments.run` builds it, written by the driver's "
             f"checkpointer (`metapg_jax/host/checkpoint.py`: orbax, atomic, the last 2 kept) {rows[0]['writes']} "
             f"times into a temporary folder on the machine's disk; median seconds per write and bytes on disk, "
             f"with the replay buffers empty (a new run) and full (every row random: the most a checkpoint holds). "
             f"Raw numbers: `{meta['json']}`.", "",
             "| run | seeds | replay rows per seed | state in memory (MiB) | empty: s | empty: MiB on disk | full: s "
             "| full: MiB on disk | full: MiB/s |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        e, f = r["empty"], r["full"]
        lines.append(f"| {r['case']}: `{' '.join(r['argv'])}` ({r['physics']}) | {r['seeds']} | "
                     f"{r['buffer_capacity']:,} | {_mib(r['state_bytes'])} | {e['median_s']:.2f} | {_mib(e['bytes'])} | "
                     f"{f['median_s']:.2f} | {_mib(f['bytes'])} | {f['bytes'] / 2**20 / f['median_s']:,.0f} |")
    worst = max(rows, key=lambda r: r["full"]["median_s"])
    verdict = "within" if worst["full"]["median_s"] < grace else "more than"
    lines += ["", f"The costliest, {worst['case']} with full buffers, takes {worst['full']['median_s']:.1f} s: "
                  f"{verdict} the default --term-grace of {grace:g} s."]
    return "\n".join(lines)


def sigterm_markdown(rows: list[dict], meta: dict, steps: int) -> str:
    """The SIGTERM table: each grace's exit, checkpoint and lost training."""
    lines = [f"## What a SIGTERM loses ({meta['date']}, commit {meta['commit'][:7]}"
             f"{' (uncommitted changes)' if meta.get('dirty') else ''})", "",
             f"`python -m experiments.bench --checkpoint-sigterm`: {meta['machine']}, JAX {meta['jax']}, "
             f"{meta['backend']}; {meta['conditions']}. `python -m experiments.run {' '.join(MAIN_JOB)} "
             f"--steps={steps} --term-grace=G` in a fresh process (its programs from a compile cache the first run "
             f"filled), sent SIGTERM a moment after its chunk {rows[0]['chunks_before_signal']} was recorded, before "
             f"its first checkpoint (the default 5-minute cadence). Lost: the seconds of training before the "
             f"signal that no checkpoint holds. Raw numbers: `{meta['json']}`.", "",
             "| --term-grace (s) | median chunk (s) | signal, s into the chunk | exit status | exit, s after the signal "
             "| checkpoint holds (chunks) | training lost (s) |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['grace_s']:g} | {r['chunk_s']:.1f} | {r['signal_into_chunk_s']:.1f} | {r['status']} | "
                     f"{r['exit_after_s']:.1f} | {r['checkpointed_chunks'] or 'none'} | {r['lost_s']:.1f} |")
    lines += [""] + [f"- `--term-grace={r['grace_s']:g}`: {r['last_line']}" for r in rows]
    return "\n".join(lines)
