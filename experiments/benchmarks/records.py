"""Where the benchmark records go and how they are written: the default folder, the targets the
tables check, each generated section of ``BENCHMARKS.md`` replaced in place, and the row labels
(date, variant) the tables and ratios group by."""

from __future__ import annotations

import os

from metapg_jax.host.runfiles import write_text_atomic

BENCH_DIR = "results/benchmarks"  # where the records go by default (relative to the repository root)
TARGETS = {"overhead": 1.2, "scaling_8": 2.5, "compile_s": 60.0, "rss_over_buffer": 2.0,
           "main_job_compile_s": 30.0}  # the README's main job on its default engine, cold, on a 2-core CPU


def write_section(path: str, name: str, text: str) -> None:
    """Replaces the generated section ``name`` of ``path`` (between marker comments), keeping
    everything else in the file (the hand-written analysis); appends it if it is not there."""
    begin, end = f"<!-- bench:{name} (generated) -->", f"<!-- /bench:{name} -->"
    old = open(path).read() if os.path.exists(path) else "# Benchmarks\n"
    block = f"{begin}\n{text.rstrip()}\n{end}"
    if begin in old and end in old:
        new = old[:old.index(begin)] + block + old[old.index(end) + len(end):]
    else:
        new = old.rstrip() + "\n\n" + block + "\n"
    write_text_atomic(path, new)


def _date(r: dict) -> str:
    return r.get("measured", "undated")


def _variant(r: dict) -> str:
    return (" (MuJoCo C)" if r.get("physics") == "mujoco" else "") + (
        " (stock MJX line search)" if r.get("stock_mjx") else "") + (" (plain vmap)" if r.get("plain_vmap") else "")

