"""Check a stored cell against its recorded commit: re-run its first evaluation intervals from a clean
checkout of the commit it started at, and compare the metrics with the stored ones.

    python -m experiments.verify results/cells/hopper/ddpg-normal           # the first interval
    python -m experiments.verify results/td3/cells/*/td3-normal --chunks 2

For a cell recorded as run from a tree with uncommitted changes and no stored diff (``dirty`` in its
``config.json`` or ``reproduce.json``; ``experiments.analysis.cells.is_dirty``), this tells whether those changes
touched the training program: the compiled run is deterministic, so the clean commit gives the stored
numbers if they did not. The cell's first recorded command (``reproduce.json``'s first call; else its
``run_args``) runs with ``--steps`` cut to ``--chunks`` evaluation intervals, the cell's own
``run.eval_every`` and the replay capacity of that first command (a shorter budget with the same capacity
gives the same first intervals: ``docs/long-runs.md``), in a ``git worktree`` of the commit, with this Python. Its
metrics rows are compared with the stored rows of the same chunks and seeds, field by field (timings
left out). The result goes to ``<cell>/verified.json`` (the command, the commit, both numbers per seed,
the largest relative difference and the verdict: ``reproduced`` when every compared value agrees within
``--rtol``, else ``differs``; ``same_cpu`` and ``same_packages``: whether the cell was recorded on this CPU and
with these versions of ``provenance.PACKAGES``; None where its record predates them), which the results
manifest and footers report. Bit-for-bit equality needs the CPU the cell ran on (XLA compiles for the CPU
it runs on; ``metapg_jax.host.provenance.cpu_fingerprint``, recorded with every run): on another CPU a
chaotic task's re-run differs after round-off grows, and ``differs`` says nothing about the code. A budget
extension run from a later, dirty tree is not covered: its code starts after the first intervals.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULT = "verified.json"
# Metrics that measure time, not training: never compared.
TIMINGS = {"wall_time", "chunk_seconds"}


def cell_command(cell: str) -> tuple[str, list[str], int]:
    """(commit, run options, eval_every) of a stored cell: the commit it started at (config.json) and its
    first recorded command (reproduce.json), or one rebuilt from its run_args, with the replay capacity that
    command ran with made explicit (a shorter ``--steps`` would otherwise shrink it)."""
    with open(os.path.join(cell, "config.json")) as f:
        stored = json.load(f)
    commit = stored.get("commit")
    if not commit or commit == "unknown":
        raise ValueError(f"{cell}: config.json records no commit")
    calls = []
    if os.path.exists(os.path.join(cell, "reproduce.json")):
        with open(os.path.join(cell, "reproduce.json")) as f:
            calls = json.load(f).get("calls") or []
    if calls:
        argv = list(calls[0]["argv"])
    else:
        a = stored["run_args"]
        argv = [f"--{k}={a[k]}" for k in ("env", "method", "teacher", "noise", "preset", "seeds", "seed", "source",
                                           "physics", "student") if a.get(k) is not None]
        for s in a.get("overrides") or []:
            argv += ["--set", s]
    run = stored["config"]["run"]
    # The replay capacity the first call ran with (its shapes are part of the compiled program): the config's,
    # or min(1e6, the first call's budget) for 0 (an extension stores its longer budget in config.json).
    steps = next((int(a.split("=", 1)[1]) for a in argv if a.startswith("--steps=")), None)
    if steps is None and "--steps" in argv:
        steps = int(argv[argv.index("--steps") + 1])
    first_budget = steps or (stored.get("extensions") or [{}])[0].get("from_steps") or int(run["total_steps"])
    capacity = int(run.get("buffer_size") or 0) or min(1_000_000, int(first_budget))
    return commit, argv + ["--set", f"run.buffer_size={capacity}"], int(run["eval_every"])


def _replace(argv: list[str], flag: str, value: str | None) -> list[str]:
    """``argv`` without ``flag`` (as ``--flag=x`` or ``--flag x``), then ``--flag=value`` when given."""
    out, skip = [], False
    for a in argv:
        if skip:
            skip = False
            continue
        if a == flag:
            skip = True
            continue
        if a.startswith(flag + "="):
            continue
        out.append(a)
    return out + ([f"{flag}={value}"] if value is not None else [])


def compare(stored: list[dict], rerun: list[dict], chunks: int, rtol: float) -> dict:
    """Per seed, the stored and re-run numbers of the first ``chunks`` chunks, field by field (timings left
    out); the largest relative difference and the verdict."""
    key = lambda r: (int(r["seed"]), int(r["chunk"]))
    want = {key(r): r for r in stored if int(r["chunk"]) < chunks}
    got = {key(r): r for r in rerun if int(r["chunk"]) < chunks}
    if not want or set(want) != set(got):
        return {"verdict": "differs", "why": f"rows differ: stored {sorted(want)}, re-run {sorted(got)}",
                "max_relative_difference": None, "rows": []}
    worst, rows = 0.0, []
    for k in sorted(want):
        a, b = want[k], got[k]
        fields = sorted(f for f in a.keys() & b.keys() if f not in TIMINGS and f not in ("seed", "chunk")
                        and isinstance(a[f], (int, float)) and isinstance(b[f], (int, float)))
        for f in fields:
            x, y = float(a[f]), float(b[f])
            if math.isnan(x) and math.isnan(y):
                continue
            rel = abs(x - y) / max(abs(x), abs(y), 1e-12)
            worst = max(worst, rel if math.isfinite(rel) else math.inf)
        rows.append({"seed": k[0], "chunk": k[1], "stored_eval_return": a.get("eval_return"),
                     "rerun_eval_return": b.get("eval_return"), "fields_compared": len(fields)})
    return {"verdict": "reproduced" if worst <= rtol else "differs", "max_relative_difference": worst,
            "rows": rows}


def _recorded_machine(cell: str) -> dict:
    with open(os.path.join(cell, "config.json")) as f:
        return json.load(f).get("machine", {})


def _same_cpu(cell: str) -> bool | None:
    """Whether the cell's first run recorded this machine's CPU fingerprint (``provenance.cpu_fingerprint``);
    None for a cell recorded before fingerprints were. XLA compiles for the CPU it runs on: on another CPU a
    re-run of the same commit may differ by round-off, which a chaotic task grows into other numbers."""
    from metapg_jax.host import provenance

    cpu = _recorded_machine(cell).get("cpu")
    return None if cpu is None else cpu == provenance.cpu_fingerprint()


def _same_packages(cell: str) -> bool | None:
    """Whether the cell's first run recorded this machine's versions of ``provenance.PACKAGES`` (None for a cell
    recorded before they were): another jaxlib or MuJoCo build may round differently, as another CPU may."""
    from metapg_jax.host import provenance

    packages = _recorded_machine(cell).get("packages")
    return None if packages is None else packages == provenance.package_versions(tuple(packages))


def verify(cell: str, chunks: int = 1, rtol: float = 1e-5, keep: str | None = None, at: str | None = None) -> dict:
    """Re-runs the cell's first ``chunks`` intervals at its commit, or at ``at`` (another commit, e.g. the one
    that committed the changes a dirty cell ran with; recorded as such), see the module docstring; returns
    the record written to ``<cell>/verified.json``."""
    from metapg_jax.host import provenance, runfiles

    recorded, argv, eval_every = cell_command(cell)
    commit = recorded if at is None else subprocess.run(["git", "rev-parse", at], cwd=ROOT, capture_output=True,
                                                        text=True, check=True).stdout.strip()
    work = keep or tempfile.mkdtemp(prefix="metapg-verify-")
    src, out = os.path.join(work, "src"), os.path.join(work, "run")
    argv = _replace(_replace(_replace(argv, "--out", None), "--steps", str(chunks * eval_every)), "--resume", None)
    argv += ["--set", f"run.eval_every={eval_every}", "--out", out]  # a shorter budget keeps the cell's interval
    try:
        subprocess.run(["git", "worktree", "add", "--detach", "-f", src, commit], cwd=ROOT, check=True,
                       capture_output=True, text=True)
        env = {**os.environ, "PYTHONPATH": src, "JAX_PLATFORMS": os.environ.get("JAX_PLATFORMS", "cpu")}
        proc = subprocess.run([sys.executable, "-m", "experiments.run", *argv], cwd=src, env=env,
                              capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(f"the run at {commit[:7]} exited {proc.returncode}: "
                               + (proc.stderr.strip().splitlines() or ["(no output)"])[-1])
        result = compare(runfiles.read_jsonl(os.path.join(cell, "metrics.jsonl")),
                         runfiles.read_jsonl(os.path.join(out, "metrics.jsonl")), chunks, rtol)
    finally:
        subprocess.run(["git", "worktree", "remove", "--force", src], cwd=ROOT, capture_output=True)
        if keep is None:
            shutil.rmtree(work, ignore_errors=True)
    record = {"commit": commit, **({} if commit == recorded else {"recorded_commit": recorded}),
              "command": ["python", "-m", "experiments.run", *argv[:-2], "--out", "<tmp>"],
              "chunks": chunks, "env_steps": chunks * eval_every, "rtol": rtol, **result,
              "same_cpu": _same_cpu(cell), "same_packages": _same_packages(cell),
              "checked": {"date": datetime.date.today().isoformat(), **provenance.record()}}
    runfiles.write_json_atomic(os.path.join(cell, RESULT), record)
    return record


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.verify", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("cells", nargs="+", help="stored cell folders (config.json, metrics.jsonl, reproduce.json)")
    p.add_argument("--chunks", type=int, default=1, help="evaluation intervals to re-run (default 1)")
    p.add_argument("--rtol", type=float, default=1e-5, help="largest relative difference that still agrees")
    p.add_argument("--keep", default=None, help="keep the checkout and the run in this folder (one cell only)")
    p.add_argument("--at", default=None, metavar="COMMIT",
                   help="re-run at this commit instead of the recorded one (e.g. the commit that holds the changes "
                        "a dirty cell ran with); the record names both")
    a = p.parse_args(argv)
    bad = [c for c in a.cells if not (os.path.isfile(os.path.join(c, "config.json"))
                                      and os.path.isfile(os.path.join(c, "metrics.jsonl")))]
    if bad or a.chunks < 1 or not a.rtol >= 0 or (a.keep and len(a.cells) > 1):
        print("error: " + (f"not a stored cell (config.json and metrics.jsonl): {', '.join(bad)}" if bad else
                           "--chunks must be >= 1" if a.chunks < 1 else "--rtol must be >= 0" if not a.rtol >= 0
                           else "--keep takes one cell"), file=sys.stderr)
        return 2
    status = 0
    for cell in a.cells:
        try:
            r = verify(cell, a.chunks, a.rtol, a.keep, a.at)
        except (RuntimeError, ValueError, OSError, subprocess.CalledProcessError) as err:
            print(f"{cell}: error: {getattr(err, 'stderr', None) or err}".strip(), file=sys.stderr)
            status = 1
            continue
        note = ""
        if r["verdict"] != "reproduced" and not (r["same_cpu"] and r["same_packages"]):
            unknown = [w for w, k in (("CPU", "same_cpu"), ("package versions", "same_packages")) if r[k] is None]
            other = [w for w, k in (("another CPU", "same_cpu"), ("other package versions", "same_packages"))
                     if r[k] is False]
            note = ("; recorded with " + " and ".join(other) if other else "") + (
                f"; the cell's {' and '.join(unknown)} not recorded" if unknown else "") + (
                " (bit-for-bit equality needs the same CPU and packages)")
        print(f"{cell}: {r['verdict']} at {r['commit'][:7]}"
              + (f" (recorded: {r['recorded_commit'][:7]})" if "recorded_commit" in r else "")
              + f" over {r['env_steps']:,} env steps (largest relative difference {r['max_relative_difference']})"
              + note, flush=True)
        status = status or (0 if r["verdict"] == "reproduced" else 1)
    return status


if __name__ == "__main__":
    sys.exit(main())
