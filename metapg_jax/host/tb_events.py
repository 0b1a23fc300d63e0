"""The rows of ``metrics.jsonl`` and ``cycles.jsonl`` as TensorBoard scalars (``--tensorboard``), written
as TFRecord event files that a resumed run truncates to its checkpoint, and the run's logger that writes them."""

from __future__ import annotations

import os
import struct
import time
from typing import Any, Iterable

from metapg_jax.host.loggers import Logger, finished_rows
from metapg_jax.host.metric_rows import scalars


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
    ...) at its ``env_steps``; each field of a :func:`cycle_rows` row as ``<cycle_prefix><name>`` (the run
    passes its explorer's name: ``meta/meta_reward``) at the env
    steps stored by the end of that cycle, ``(cycle + 1) * steps_per_cycle`` (every cycle stores exactly
    that many; ``config.validate``), so all curves share one x axis. The values are the rows' own, so
    TensorBoard shows the numbers of the JSONL files (as float32, the event format's scalar); None
    (NaN or inf in the rows), booleans and non-numbers are skipped.

    Events go through tensorboardX's synchronous ``EventsWriter`` and are flushed and fsynced after every
    batch, like :class:`JsonlWriter` (tensorboardX's ``SummaryWriter`` hands events to a thread, and its
    ``flush()`` does not wait for that queue). Each seed's events are written in env-step order (a chunk's cycles,
    then its evaluation). tensorboardX is imported here, lazily: it is an optional extra.
    """

    def __init__(self, folder: str, steps_per_cycle: int, cycle_prefix: str = "cycle/"):
        from tensorboardX.event_file_writer import EventsWriter
        from tensorboardX.proto import event_pb2, summary_pb2

        self._events_writer, self._event_pb2, self._summary_pb2 = EventsWriter, event_pb2, summary_pb2
        self.folder = folder
        self.steps_per_cycle = steps_per_cycle
        if not cycle_prefix.endswith("/") or "/" in cycle_prefix[:-1]:
            raise ValueError(f"cycle_prefix must be one name and a slash, got {cycle_prefix!r}")
        self.cycle_prefix = cycle_prefix
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
            events.setdefault(int(row["seed"]), []).append((self.cycle_step(row), self.cycle_prefix, row))
        for row in metric_rows:
            events.setdefault(int(row["seed"]), []).append((int(row["env_steps"]), "", row))
        for seed, items in events.items():
            writer = self._writer(seed)
            for step, prefix, row in sorted(items, key=lambda item: item[0]):  # stable: cycles first
                values = [self._summary_pb2.Summary.Value(tag=prefix + k, simple_value=v)
                          for k, v in scalars(row).items()]
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
            last = {"": 0, "cycle": 0}  # the latest step written, per kind of row
            for path in _event_files(self.seed_folder(seed)):
                records, complete = _read_records(path)
                kept = []
                for data in records:
                    event = self._event_pb2.Event.FromString(data)
                    if event.HasField("summary") and event.step > done_steps:
                        continue
                    kept.append(data)
                    for value in event.summary.value:
                        # Cycle rows' tags have a prefix (older runs: 'teacher/'), metric rows' none.
                        kind = "cycle" if "/" in value.tag else ""
                        last[kind] = max(last[kind], int(event.step))
                if len(kept) < len(records) or not complete:
                    _write_records_atomic(path, kept)
            self.write([r for r in metric_rows if int(r["seed"]) == seed and last[""] < r["env_steps"] <= done_steps],
                       [r for r in cycle_rows if int(r["seed"]) == seed
                        and last["cycle"] < self.cycle_step(r) <= done_steps])

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


class TensorBoard(Logger):
    """A run's rows as TensorBoard scalars under ``<out>/tensorboard/seed_<i>/`` (``TensorBoardWriter``; cycle
    rows tagged ``<method>/<name>``), flushed per chunk. A resumed run's event files are first cut back to its
    checkpoint and given the finished rows they lack (``TensorBoardWriter.resume``)."""

    def __init__(self):
        self._writer: TensorBoardWriter | None = None

    def start(self, cfg: Any, run_args: dict, out: str, resumed_from: int) -> None:
        del run_args
        self._writer = TensorBoardWriter(os.path.join(out, "tensorboard"), cfg.steps_per_cycle,
                                         cycle_prefix=f"{cfg.run.method}/")
        if resumed_from:
            self._writer.resume(*finished_rows(out), resumed_from * cfg.run.eval_every)

    def chunk(self, rows: list[dict], cycles: list[dict]) -> None:
        self._writer.write(rows, cycles)

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
            self._writer = None


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
