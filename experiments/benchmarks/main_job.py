"""The README's main job as a user runs it (``python -m experiments.bench --main-job``): cold compile
and env steps/s per engine, from a fresh ``experiments.run`` process; and its table."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

from experiments.benchmarks.records import TARGETS

MAIN_JOB = ["--env=inverted_double_pendulum", "--seeds=8"]  # the README's first command


def measure_main_job(physics: str, steps: int) -> dict:
    """The README's main job (``MAIN_JOB``) run as a user runs it, in a fresh subprocess, cut at ``steps``
    env steps per seed: its cold compile (no persistent compile cache) and its env steps/s over those
    steps (all seeds, evaluations included), from the run's own summary.json. ``physics``: the
    ``--physics`` value ('default' passes none: the command exactly as the README gives it)."""
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "run")
        argv = [sys.executable, "-m", "experiments.run", *MAIN_JOB, f"--steps={steps}", "--compile-cache=off",
                "--quiet", "--no-plot", f"--out={out}"] + ([] if physics == "default" else [f"--physics={physics}"])
        t = time.perf_counter()
        res = subprocess.run(argv, capture_output=True, text=True)
        wall = time.perf_counter() - t
        if res.returncode != 0:
            raise RuntimeError(f"main job ({physics}) failed: {res.stderr[-2000:]}")
        with open(os.path.join(out, "summary.json")) as f:
            summary = json.load(f)
    return {"physics_flag": physics, "physics": summary["physics"], "steps_per_seed": steps,
            "seeds": summary["num_seeds"], "compile_s": summary["compile_seconds"],
            "train_s": summary["train_seconds"], "steps_per_s_total": summary["env_steps_per_second_total"],
            "wall_s": round(wall, 1), "peak_rss_mib": summary["peak_rss_mib"]}


def main_job_markdown(rows: list[dict], meta: dict) -> str:
    target = TARGETS["main_job_compile_s"]
    commit = f", commit {meta['commit'][:7]}{' (dirty)' if meta.get('dirty') else ''}" if meta.get("commit") else ""
    lines = [f"## The main job ({meta['date']}, {meta['machine']}, JAX {meta['jax']}, {meta['backend']}{commit})", "",
             f"`python -m experiments.bench --main-job`: `python -m experiments.run {' '.join(MAIN_JOB)}` in a fresh "
             f"process with no compile cache, cut at {rows[0]['steps_per_seed']:,} env steps per seed; one run per "
             f"engine, one after the other. Compile: the cold compile the run prints; rate: env steps per second over "
             f"all seeds (evaluations included) from its summary.json. Target: the default engine compiles in "
             f"<= {target:.0f} s on a 2-core CPU. Raw numbers: `{meta['json']}`.", "",
             "| --physics | engine | compile (s) | env steps/s total | train (s) | whole command (s) | peak RSS (MiB) |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['physics_flag']} | {r['physics']} | {r['compile_s']:.1f} | {r['steps_per_s_total']:,.0f} | "
                     f"{r['train_s']:.1f} | {r['wall_s']:.1f} | {r['peak_rss_mib']:,.0f} |")
    default = next((r for r in rows if r["physics_flag"] == "default"), None)
    if default is not None:
        verdict = "met" if default["compile_s"] <= target else "missed"
        lines += ["", f"Default engine ({default['physics']}): compile {default['compile_s']:.1f} s, target {verdict}."]
        mjx = next((r for r in rows if r["physics"] == "mjx" and r is not default), None)
        if mjx is not None and default["physics"] != "mjx":
            lines.append(f"Against MJX in the same run: compile {mjx['compile_s'] / default['compile_s']:.1f}x faster, "
                         f"training {default['steps_per_s_total'] / mjx['steps_per_s_total']:.1f}x faster.")
    return "\n".join(lines)

