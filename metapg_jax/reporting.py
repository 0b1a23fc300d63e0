"""Host-side reporting: metrics files, atomic writes, progress bar, plots, summaries.

Nothing here runs inside ``jit``. The training program returns metrics per
chunk; the host turns them into one JSON line per seed per chunk
(``metrics.jsonl``, appended and flushed as they come), per-cycle lines for
the meta method (``cycles.jsonl``), a learning-curve PNG and ``summary.json``; with
``--tensorboard`` the same rows as TensorBoard scalars too (:class:`TensorBoardWriter`).
"""

from __future__ import annotations

import json
import math
import os
import struct
import sys
import tempfile
import time
from typing import Any, Iterable

import numpy as np


def _git(*args: str) -> str:
    """A git command's output in the project's checkout ('' when git fails or is missing)."""
    import subprocess

    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    try:
        return subprocess.run(["git", *args], cwd=root, capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


# Tracked files outside ``results/``: the code a run's provenance speaks for (``results/`` holds outputs).
_CODE = ("--", ".", ":(exclude)results")


def provenance() -> dict:
    """The commit (and whether the tree had changes) and the machine, recorded with every run.

    ``dirty``: tracked files outside ``results/`` differ from the commit. ``results/`` holds outputs (reports
    that a grid or screen rewrites between its cells), not code, so a rewritten report does not mark the
    cells that start after it. ``uncommitted_diff`` gives the changes themselves."""
    import platform

    machine = {"platform": platform.platform(), "processor": platform.machine(),
               "cpu_count": os.cpu_count(), "python": platform.python_version()}
    try:
        import jax

        machine.update(jax_version=jax.__version__, jax_backend=jax.default_backend(),
                       jax_devices=[str(d) for d in jax.devices()])
    except Exception as err:  # noqa: BLE001 - provenance must never stop a run
        machine["jax_error"] = repr(err)
    return {"commit": _git("rev-parse", "HEAD") or "unknown",
            "dirty": bool(_git("status", "--porcelain", "--untracked-files=no", *_CODE)),
            "machine": machine}


def uncommitted_diff() -> str:
    """The uncommitted changes that make ``provenance()`` dirty: ``git diff HEAD`` of the tracked files outside
    ``results/`` ('' for a clean tree)."""
    return _git("diff", "HEAD", "--no-color", *_CODE)


def write_json_atomic(path: str, obj: Any) -> None:
    """Writes JSON to a temporary file in the same folder, then renames it over ``path``."""
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".tmp-", suffix=".json")
    try:
        with os.fdopen(fd, "w") as f:
            json.dump(obj, f, indent=2, default=_jsonable)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _jsonable(x):
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    raise TypeError(f"not JSON serialisable: {type(x)}")


def json_number(x: float) -> float | None:
    """A number for JSON: None for NaN and infinities."""
    x = float(x)
    return None if math.isnan(x) or math.isinf(x) else x


class JsonlWriter:
    """Appends JSON lines and flushes after every batch, so a killed run keeps what it wrote."""

    def __init__(self, path: str):
        self.path = path
        self._f = open(path, "a")

    def write(self, rows: Iterable[dict]) -> None:
        for row in rows:
            self._f.write(json.dumps(row, default=_jsonable) + "\n")
        self._f.flush()
        os.fsync(self._f.fileno())

    def close(self) -> None:
        self._f.close()


def truncate_jsonl(path: str, keep) -> None:
    """Keeps the rows for which ``keep(row)`` holds (drops rows written after a checkpoint), atomically."""
    if not os.path.exists(path):
        return
    kept = [row for row in read_jsonl(path) if keep(row)]
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.writelines(json.dumps(row) + "\n" for row in kept)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def read_jsonl(path: str) -> list[dict]:
    """The rows of a JSONL file; a last line cut by a kill is skipped."""
    rows = []
    with open(path) as f:
        for line in f:
            if not line.strip():
                continue
            try:
                rows.append(json.loads(line))
            except json.JSONDecodeError:
                continue
    return rows


def savez_atomic(path: str, arrays: dict) -> None:
    """``np.savez_compressed`` to a temporary name in the same folder, then renamed over ``path``."""
    tmp = path + ".tmp.npz"
    np.savez_compressed(tmp, **arrays)
    os.replace(tmp, path)


def _train_return(cyc: dict, i: int) -> float | None:
    """Seed ``i``'s mean return of the exploring episodes completed in the chunk: weighted by the cycles'
    ``train_episodes`` where the explorer reports them (the built-in ones do), else the mean over cycles;
    None for an explorer that reports no ``train_return``, or when no episode ended."""
    if "train_return" not in cyc:
        return None
    if "train_episodes" not in cyc:
        v = np.asarray(cyc["train_return"][i], np.float64)
        return json_number(np.nanmean(v)) if np.isfinite(v).any() else None
    n_eps = cyc["train_episodes"][i].sum()
    return json_number(np.nansum(cyc["train_return"][i] * cyc["train_episodes"][i]) / n_eps) if n_eps > 0 else None


def chunk_rows(metrics: dict, chunk: int, wall_time: float, chunk_seconds: float | None = None) -> list[dict]:
    """One row per seed from a chunk's metrics (numpy, leading seed axis).

    ``wall_time``: seconds since this process started training (after compiling; a resumed call starts
    again from 0); ``chunk_seconds``: this chunk's own training time, so :func:`training_seconds` can add up
    a run's calls exactly."""
    cyc = metrics["cycle"]
    num_seeds = metrics["env_steps"].shape[0]
    rows = []
    for i in range(num_seeds):
        eval_ret = np.asarray(metrics["eval_return"][i])
        row = {
            "seed": i,
            "chunk": chunk,
            "env_steps": int(metrics["env_steps"][i]),
            "updates": int(metrics["updates"][i]),
            "eval_return": json_number(eval_ret.mean()),
            "eval_return_std": json_number(eval_ret.std()),
            "eval_length": json_number(np.mean(metrics["eval_length"][i])),
            "train_return": _train_return(cyc, i),
            "wall_time": round(wall_time, 3),
        }
        if chunk_seconds is not None:
            row["chunk_seconds"] = round(chunk_seconds, 3)
        for name, values in cyc.items():
            if name in ("train_return", "train_episodes", "finite") or np.ndim(values[i]) != 1:
                continue
            v = np.asarray(values[i], np.float64)
            row[name] = json_number(np.nanmean(v)) if np.isfinite(v).any() else None
        rows.append(row)
    return rows


def cycle_rows(metrics: dict, names: Iterable[str], first_cycle: int) -> list[dict]:
    """Per-cycle, per-seed rows of selected cycle metrics (used for the teacher's curves)."""
    cyc = metrics["cycle"]
    names = [n for n in names if n in cyc]
    if not names:
        return []
    num_seeds, num_cycles = np.shape(cyc[names[0]])[:2]
    return [
        {"seed": i, "cycle": first_cycle + c, **{n: json_number(cyc[n][i][c]) for n in names}}
        for i in range(num_seeds) for c in range(num_cycles)
    ]


def require_tensorboard() -> None:
    """Raises a one-line ``ValueError`` naming the extra if tensorboardX (the ``tensorboard`` extra, which
    :class:`TensorBoardWriter` needs) cannot be imported: the ``--tensorboard`` check of the CLIs."""
    try:
        import tensorboardX  # noqa: F401
    except ImportError:
        raise ValueError('--tensorboard needs tensorboardX: pip install -e ".[tensorboard]" '
                         '(or pip install tensorboardX)') from None


class TensorBoardWriter:
    """The rows of ``metrics.jsonl`` and ``cycles.jsonl`` as TensorBoard scalars, one run per seed.

    Seed ``i`` writes to ``<folder>/seed_<i>/``, so TensorBoard shows the seeds as separate runs. Tags:
    each numeric field of a :func:`chunk_rows` row under its own name (``eval_return``, ``critic_loss``,
    ...) at its ``env_steps``; each field of a :func:`cycle_rows` row as ``teacher/<name>`` at the env
    steps stored by the end of that cycle, ``(cycle + 1) * steps_per_cycle`` (every cycle stores exactly
    that many; ``config.validate``), so all curves share one x axis. The values are the rows' own, so
    TensorBoard shows the numbers of the JSONL files (as float32, the event format's scalar); None
    (NaN or inf in the rows), booleans and non-numbers are skipped.

    Events go through tensorboardX's synchronous ``EventsWriter`` and are flushed and fsynced after every
    batch, like :class:`JsonlWriter` (tensorboardX's ``SummaryWriter`` hands events to a thread, and its
    ``flush()`` does not wait for that queue). Each seed's events are written in env-step order (a chunk's cycles,
    then its evaluation). tensorboardX is imported here, lazily: it is an optional extra.
    """

    def __init__(self, folder: str, steps_per_cycle: int):
        from tensorboardX.event_file_writer import EventsWriter
        from tensorboardX.proto import event_pb2, summary_pb2

        self._events_writer, self._event_pb2, self._summary_pb2 = EventsWriter, event_pb2, summary_pb2
        self.folder = folder
        self.steps_per_cycle = steps_per_cycle
        self._writers: dict[int, Any] = {}

    def seed_folder(self, seed: int) -> str:
        return os.path.join(self.folder, f"seed_{seed}")

    def cycle_step(self, row: dict) -> int:
        """The x value of a cycle row: env steps stored by the end of its cycle."""
        return (int(row["cycle"]) + 1) * self.steps_per_cycle

    def write(self, metric_rows: Iterable[dict], cycle_rows: Iterable[dict] = ()) -> None:
        """Appends the scalars of a batch of rows (any seeds), then flushes every seed's file."""
        events: dict[int, list] = {}
        for row in cycle_rows:  # first: a chunk's last cycle ends at its evaluation's step
            events.setdefault(int(row["seed"]), []).append((self.cycle_step(row), "teacher/", row))
        for row in metric_rows:
            events.setdefault(int(row["seed"]), []).append((int(row["env_steps"]), "", row))
        for seed, items in events.items():
            writer = self._writer(seed)
            for step, prefix, row in sorted(items, key=lambda item: item[0]):  # stable: cycles first
                values = [self._summary_pb2.Summary.Value(tag=prefix + k, simple_value=float(v))
                          for k, v in row.items() if k not in _NOT_SCALARS and _is_number(v)]
                if values:
                    writer.write_event(self._event_pb2.Event(wall_time=time.time(), step=step,
                                                             summary=self._summary_pb2.Summary(value=values)))
            writer.flush()

    def resume(self, metric_rows: list[dict], cycle_rows: list[dict], done_steps: int) -> None:
        """Before a resumed run appends: makes the event files end at its checkpoint and hold every row to it.

        Events past ``done_steps`` (chunks after the checkpoint, which the resume runs again) are dropped
        from the files, as the resume drops those rows from the JSONL files; then the finished rows (the
        JSONL files' rows up to ``done_steps``) past each seed's last event are written: all of them for
        a run that had no TensorBoard output, the missing tail for one resumed without it in between."""
        seeds = {int(r["seed"]) for r in metric_rows} | {int(r["seed"]) for r in cycle_rows}
        if os.path.isdir(self.folder):
            seeds |= {int(name[5:]) for name in os.listdir(self.folder)
                      if name.startswith("seed_") and name[5:].isdigit()}
        for seed in sorted(seeds):
            last = {"": 0, "teacher/": 0}  # the latest step written, per kind of row
            for path in _event_files(self.seed_folder(seed)):
                records, complete = _read_records(path)
                kept = []
                for data in records:
                    event = self._event_pb2.Event.FromString(data)
                    if event.HasField("summary") and event.step > done_steps:
                        continue
                    kept.append(data)
                    for value in event.summary.value:
                        kind = "teacher/" if value.tag.startswith("teacher/") else ""
                        last[kind] = max(last[kind], int(event.step))
                if len(kept) < len(records) or not complete:
                    _write_records_atomic(path, kept)
            self.write([r for r in metric_rows if int(r["seed"]) == seed and last[""] < r["env_steps"] <= done_steps],
                       [r for r in cycle_rows if int(r["seed"]) == seed
                        and last["teacher/"] < self.cycle_step(r) <= done_steps])

    def _writer(self, seed: int):
        if seed not in self._writers:
            folder = self.seed_folder(seed)
            os.makedirs(folder, exist_ok=True)
            # Event files are named by the second they were opened; the suffix keeps a resume within the
            # same second from overwriting the previous file (EventsWriter truncates).
            self._writers[seed] = self._events_writer(os.path.join(folder, "events"),
                                                      f".{len(_event_files(folder))}")
        return self._writers[seed]

    def close(self) -> None:
        for writer in self._writers.values():
            writer.close()
        self._writers = {}


# Fields of the rows that are not metrics: which seed, which chunk or cycle, and the x axis.
_NOT_SCALARS = frozenset({"seed", "chunk", "cycle", "env_steps"})


def _is_number(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_)) \
        and math.isfinite(v)


def _event_files(folder: str) -> list[str]:
    """A run folder's event files in the order TensorBoard reads them (by name)."""
    if not os.path.isdir(folder):
        return []
    return [os.path.join(folder, n) for n in sorted(os.listdir(folder)) if ".tfevents." in n]


def _read_records(path: str) -> tuple[list[bytes], bool]:
    """(the TFRecord payloads of an event file, whether it ended on a whole record: not cut by a kill)."""
    records = []
    with open(path, "rb") as f:
        while True:
            header = f.read(12)  # uint64 length, uint32 masked CRC of it
            if not header:
                return records, True
            if len(header) < 12:
                return records, False
            (length,) = struct.unpack("<Q", header[:8])
            data = f.read(length)
            if len(data) < length or len(f.read(4)) < 4:  # payload, uint32 masked CRC of it
                return records, False
            records.append(data)


def _write_records_atomic(path: str, records: list[bytes]) -> None:
    from tensorboardX.record_writer import RecordWriter

    tmp = os.path.join(os.path.dirname(path), ".rewrite.tmp")  # no "tfevents" in it: TensorBoard skips it
    writer = RecordWriter(tmp)
    for data in records:
        writer.write(data)
    writer.flush()
    writer.close()
    os.replace(tmp, path)


def read_tensorboard_scalars(folder: str) -> dict[str, list[tuple[int, float]]]:
    """{tag: [(step, value), ...]} of the scalars in a run folder's event files, in file order."""
    from tensorboardX.proto import event_pb2

    scalars: dict[str, list[tuple[int, float]]] = {}
    for path in _event_files(folder):
        for data in _read_records(path)[0]:
            event = event_pb2.Event.FromString(data)
            for value in event.summary.value:
                if value.WhichOneof("value") == "simple_value":
                    scalars.setdefault(value.tag, []).append((int(event.step), float(value.simple_value)))
    return scalars


class Progress:
    """A tqdm bar over env steps with steps/s, ETA and the latest mean evaluation return.

    ``initial``: env steps per seed already done before this call (a resume or an extension); the bar
    starts there, and both rates (tqdm's per-seed steps/s and the total steps/s) count only the steps
    trained in this call."""

    def __init__(self, total_steps: int, num_seeds: int, desc: str, disable: bool | None = None,
                 initial: int = 0):
        from tqdm import tqdm

        self.num_seeds = num_seeds
        self.initial = self.steps = initial  # env steps per seed: before this call, and so far
        self.start = time.perf_counter()
        self.bar = tqdm(total=total_steps, initial=initial, desc=desc, unit="step", dynamic_ncols=True,
                        disable=disable if disable is not None else False, file=sys.stderr,
                        bar_format="{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}<{remaining}, {rate_fmt}{postfix}]")

    def total_rate(self) -> float:
        """Env steps per second over all seeds, trained in this call."""
        return self.num_seeds * (self.steps - self.initial) / max(time.perf_counter() - self.start, 1e-9)

    def update(self, env_steps: int, eval_returns: np.ndarray) -> None:
        self.bar.update(env_steps - self.steps)
        self.steps = env_steps
        self.bar.set_postfix_str(
            f"eval {np.mean(eval_returns):.1f} ± {np.std(eval_returns):.1f} | {self.total_rate():,.0f} total steps/s")

    def close(self) -> None:
        self.bar.close()


def training_seconds(rows: list[dict]) -> tuple[float | None, bool]:
    """(seconds of training over all the calls that made these metrics rows, exact?); compile excluded;
    (None, False) for rows without times.

    Rows with ``chunk_seconds`` add up exactly. Older rows only have ``wall_time``, the time since their
    call started training: a chunk whose ``wall_time`` is below the previous chunk's starts a new call
    (a resume). That misses a resume whose first chunk took longer than all the previous call did (a
    call killed after a single chunk, say), so the result is then flagged not exact. The reproduce
    record's wall time misses calls killed before they could write it; this does not."""
    by_chunk: dict[int, dict] = {}
    for r in rows:
        if r.get("wall_time") is not None:
            by_chunk.setdefault(int(r["chunk"]), r)
    if not by_chunk:
        return None, False
    total, prev, exact = 0.0, None, True
    for chunk in sorted(by_chunk):
        r, wall = by_chunk[chunk], float(by_chunk[chunk]["wall_time"])
        if r.get("chunk_seconds") is not None:
            total += float(r["chunk_seconds"])
        else:
            exact = False
            total += wall if prev is None or wall < prev else wall - prev
        prev = wall
    return total, exact


def curves(rows: list[dict], key: str = "eval_return") -> tuple[np.ndarray, np.ndarray]:
    """(env_steps (T,), values (seeds, T)) from metrics rows."""
    seeds = sorted({r["seed"] for r in rows})
    by_seed = {s: sorted((r for r in rows if r["seed"] == s), key=lambda r: r["env_steps"]) for s in seeds}
    steps = np.array([r["env_steps"] for r in by_seed[seeds[0]]])
    length = min(len(v) for v in by_seed.values())
    values = np.array([[np.nan if r.get(key) is None else r[key] for r in by_seed[s][:length]] for s in seeds])
    return steps[:length], values


def plot_learning_curve(rows: list[dict], path: str, title: str, key: str = "eval_return",
                        ylabel: str = "evaluation return") -> None:
    """Mean ± std band over seeds with thin per-seed lines; x axis: env steps."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    steps, values = curves(rows, key)
    fig, ax = plt.subplots(figsize=(6.4, 4.0), dpi=120)
    for v in values:
        ax.plot(steps, v, lw=0.6, alpha=0.35, color="tab:blue")
    mean, std = np.nanmean(values, 0), np.nanstd(values, 0)
    ax.plot(steps, mean, lw=2.0, color="tab:blue", label=f"mean of {len(values)} seeds")
    ax.fill_between(steps, mean - std, mean + std, color="tab:blue", alpha=0.2, label="± std")
    ax.set_xlabel("environment steps")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
