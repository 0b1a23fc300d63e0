"""What a training run reports to besides its own record: the ``Logger`` interface that the driver
(``metapg_jax.host.driver``) calls, brax's ``progress_fn`` widened to a run's life (its start, each chunk's rows,
each checkpoint, its finish, the close), and the loggers that are not tied to an optional package: several loggers
as one, a logger of plain functions (a notebook's), and the progress bar. TensorBoard's is
``tb_events.TensorBoard``, Weights & Biases' ``wandb_runs.WandB``.
"""

from __future__ import annotations

import contextlib
import os
from typing import Any, Callable, Iterable, Protocol

import numpy as np


class Logger(Protocol):
    """A run's observer. The driver calls it on process 0, in this order: ``start`` once, after compiling and before
    the first chunk; ``chunk`` after each chunk's rows are written; ``checkpoint`` after each checkpoint; ``finish``
    once if the run trained to its budget; ``close`` always, also after a stop or an error. Each method does nothing
    by default: a logger subclasses this and overrides what it uses. Loggers only observe: nothing they do is stored
    with the run, and a resume may add or leave out any of them."""

    def start(self, cfg: Any, run_args: dict, out: str, resumed_from: int) -> None:
        """The run begins (or goes on).

        Args:
          cfg: the run's validated ``metapg_jax.config.Config``.
          run_args: the run arguments ``config.json`` stores (``seeds``, ``seed``, ...).
          out: the run folder; its ``metrics.jsonl`` and ``cycles.jsonl`` hold the finished chunks
            (``finished_rows``).
          resumed_from: chunks done before this call (0 for a new run).
        """
        del cfg, run_args, out, resumed_from

    def chunk(self, rows: list[dict], cycles: list[dict]) -> None:
        """A chunk's rows, as appended to ``metrics.jsonl`` and ``cycles.jsonl``.

        Args:
          rows: one per seed (``metric_rows.chunk_rows``): ``seed``, ``chunk``, ``env_steps``, ``eval_return``, ...
          cycles: one per seed per cycle (``metric_rows.cycle_rows``); [] for an explorer without cycle metrics.
        """
        del rows, cycles

    def checkpoint(self, chunks_done: int) -> None:
        """A checkpoint of the state after ``chunks_done`` chunks has been saved."""
        del chunks_done

    def finish(self, summary: dict) -> None:
        """The run has trained to its budget.

        Args:
          summary: the run's summary (``summary.json``'s numbers where the caller finalises the run, else the
            driver's record of the call: compile and training seconds, throughput, memory).
        """
        del summary

    def close(self) -> None:
        """The driver is done with the logger (after ``finish``, a stop or an error)."""


class Loggers(Logger):
    """Several loggers as one, each called in the order given; ``close`` closes every one even if one fails."""

    def __init__(self, loggers: Iterable[Logger] = ()):
        self._loggers = list(loggers)

    def start(self, cfg: Any, run_args: dict, out: str, resumed_from: int) -> None:
        for logger in self._loggers:
            logger.start(cfg, run_args, out, resumed_from)

    def chunk(self, rows: list[dict], cycles: list[dict]) -> None:
        for logger in self._loggers:
            logger.chunk(rows, cycles)

    def checkpoint(self, chunks_done: int) -> None:
        for logger in self._loggers:
            logger.checkpoint(chunks_done)

    def finish(self, summary: dict) -> None:
        for logger in self._loggers:
            logger.finish(summary)

    def close(self) -> None:
        with contextlib.ExitStack() as stack:  # runs every close, first given first, and re-raises the first error
            for logger in reversed(self._loggers):
                stack.callback(logger.close)
        self._loggers = []


class Callback(Logger):
    """A logger of plain functions, e.g. ``Callback(chunk=lambda rows, cycles: print(rows[0]["env_steps"]))``: a
    notebook's ``progress_fn``. ``chunk(rows, cycles)``, ``checkpoint(chunks_done)`` and ``finish(summary)`` are
    called as the ``Logger`` methods of the same names; each is optional."""

    def __init__(self, chunk: Callable[[list[dict], list[dict]], Any] | None = None,
                 checkpoint: Callable[[int], Any] | None = None, finish: Callable[[dict], Any] | None = None):
        self._chunk, self._checkpoint, self._finish = chunk, checkpoint, finish

    def chunk(self, rows: list[dict], cycles: list[dict]) -> None:
        if self._chunk is not None:
            self._chunk(rows, cycles)

    def checkpoint(self, chunks_done: int) -> None:
        if self._checkpoint is not None:
            self._checkpoint(chunks_done)

    def finish(self, summary: dict) -> None:
        if self._finish is not None:
            self._finish(summary)


class ProgressBar(Logger):
    """The terminal's progress bar over a run (``terminal.Progress``: env steps, steps/s, ETA, the latest mean ±
    std evaluation return over seeds); it starts at the steps done before this call, its rates count this call's
    steps only, and it closes at the budget's last chunk (before the lines of the finished run).

    Args:
      desc: the bar's label (``experiments.run`` gives the run's, e.g. '<task> meta/independent').
      runs: the runs its total steps/s counts (default: the run's seeds; a sweep group: settings x seeds).
    """

    def __init__(self, desc: str, runs: int | None = None):
        self._desc, self._runs = desc, runs
        self._bar, self._total = None, 0

    def start(self, cfg: Any, run_args: dict, out: str, resumed_from: int) -> None:
        from metapg_jax.host.terminal import Progress

        del out
        self._total = cfg.run.total_steps
        self._bar = Progress(self._total, self._runs or run_args["seeds"], self._desc, disable=False,
                             initial=resumed_from * cfg.run.eval_every)

    def chunk(self, rows: list[dict], cycles: list[dict]) -> None:
        del cycles
        returns = np.array([np.nan if r["eval_return"] is None else r["eval_return"] for r in rows])
        self._bar.update(int(rows[0]["env_steps"]), returns)
        if int(rows[0]["env_steps"]) >= self._total:
            self.close()

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None


def finished_rows(out: str) -> tuple[list[dict], list[dict]]:
    """(the rows of ``metrics.jsonl``, those of ``cycles.jsonl``) in a run folder: at a logger's ``start``, the
    finished chunks, cut back to the checkpoint a resume continues from ([] for a file not written yet)."""
    from metapg_jax.host.runfiles import read_jsonl

    paths = [os.path.join(out, name) for name in ("metrics.jsonl", "cycles.jsonl")]
    return tuple(read_jsonl(path) if os.path.exists(path) else [] for path in paths)
