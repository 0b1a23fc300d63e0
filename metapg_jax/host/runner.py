"""The host loop every command shares: a compiled chunk program run chunk by chunk, each chunk's metrics handed
to the caller as they come (who writes them and tells its loggers: ``driver.Recorder``), checkpoints on a cadence,
at the end and on a first Ctrl-C, and the one line that says what a stop lost and how to go on.

The training driver (``driver.run``: one run) and ``experiments.sweep`` (one program group) each open a
``ChunkLoop`` before they compile and run their program through it; what differs between them (the rows they write,
the NaN guard, what a checkpoint holds) is theirs, passed in as functions.

A SIGTERM (what a batch scheduler sends before it kills) gets a grace period (``TERM_GRACE``, ``--term-grace``): the
loop finishes the chunk in flight and checkpoints it if both can end within the grace, and stops at once otherwise
(``Signals``).
"""

from __future__ import annotations

import contextlib
import signal
import statistics
import sys
import threading
import time
from typing import Any, Callable

# Seconds a first SIGTERM leaves a chunk loop to finish its chunk in flight and checkpoint it (``--term-grace``):
# under SLURM's default KillWait and Kubernetes' default terminationGracePeriodSeconds (both 30 s), with room for
# the process to exit.
TERM_GRACE = 25.0


def check_term_grace(seconds: float, name: str = "--term-grace") -> None:
    """``ValueError`` (one line, naming the option ``name``) unless ``seconds`` is a finite number >= 0."""
    if not 0 <= seconds < float("inf"):
        raise ValueError(f"{name} must be a finite number of seconds >= 0 (0: a SIGTERM stops at once), got {seconds}")


class Stopped(Exception):
    """Raised in the host loop by a second Ctrl-C, or by a SIGTERM without a grace or whose grace cannot be met:
    stop at once (``Signals``). ``reason``: why a SIGTERM's grace could not be used, as the stop line says it ('' for
    the others)."""

    def __init__(self, signum: int, reason: str = ""):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum
        self.status = 128 + signum  # 130 (SIGINT), 143 (SIGTERM): the shells' convention
        self.reason = reason

    @property
    def who(self) -> str:
        """'Ctrl-C' (a second one) or the signal's name, as a stop line says it."""
        return "Ctrl-C" if self.signum == signal.SIGINT else self.args[0]


class Signals:
    """How a host loop stops. The first Ctrl-C sets ``requested``: the loop finishes the chunk in
    flight, checkpoints and exits 130. A second Ctrl-C raises ``Stopped`` at once (exit 130): the chunk in
    flight cannot be saved (the state it started from was donated to it). ``call`` starts a chunk from a thread of
    its own and ``wait`` blocks on its results, both in short sleeps, so that a signal is handled while a chunk
    runs, not only after it.

    A first SIGTERM while a chunk loop runs (``looping``), with a ``grace`` of more than 0 seconds, sets
    ``terminated``: the loop finishes the chunk in flight, checkpoints it and exits 143, if the chunk's expected
    remaining time plus a checkpoint's fit in what is left of the grace, else it raises ``Stopped`` at once (exit
    143), as a SIGTERM without a grace (0), one outside a loop (while a program compiles, between a grid's cells) or a
    second signal does. The estimate, made when the signal comes and again every time the loop looks at the chunk
    (so a chunk that overruns is given up in time): the chunk's remaining time is the median duration of this
    call's finished chunks (``chunk_seconds``) minus the time since it started (none finished yet: 0, so the loop
    waits as long as the grace allows); a checkpoint takes as long as this call's last one (``save_seconds``). With
    no checkpoint written yet in this call nothing is kept for it: early in a run the replay buffers are nearly
    empty and a checkpoint costs little, while giving up the chunk loses everything since the run's start; a write
    that a scheduler's kill cuts short leaves the previous checkpoint as it was (writes are atomic), which is all a
    stop at once would have left. A chunk that has ended is checkpointed.

    Python runs a handler wherever the main thread is, also inside a garbage-collection callback or a
    ``__del__``, where an exception is printed and dropped ("Exception ignored in ..."): so the handler
    also keeps the stop in ``stopped``, and ``wait`` and ``check`` raise it again.

    A command that runs several loops in turn (a grid's cells, a sweep's groups) holds its own ``Signals`` around
    them (``first``: what its first Ctrl-C does), so that a Ctrl-C between two loops is kept, not lost: it
    replaces whatever the process started with, also the ignored SIGINT that a shell gives a job it starts in the
    background. It runs each loop, with what comes before and after it (setting up, recording, archiving),
    under ``holding``: a stop is kept there instead of raised, and ``check`` raises it once that is done. A loop
    opened inside takes over the signals and starts with the outer one's stop: a first Ctrl-C that came while
    it was set up stops it after its first chunk, a SIGTERM at its first ``wait``; what it received is handed
    back to the outer one when it ends (a Ctrl-C during a run's last chunk stops the grid after that run)."""

    def __init__(self, first: str = "finishing the current chunk, then checkpointing", grace: float = 0.0):
        self.requested = False
        self.stopped: Stopped | None = None
        self.in_flight = None  # the 1-based chunk the loop is running, for the stop line
        self.grace = grace
        self.terminated: float | None = None  # when a first SIGTERM with a grace came (time.perf_counter)
        self.looping = False  # a chunk loop runs (``run_chunks``): a first SIGTERM gets the grace
        self.chunk_started: float | None = None  # when the chunk in flight started (None: none in flight)
        self.chunk_seconds: list[float] = []  # this call's chunks, from their start to their record
        self.save_seconds: float | None = None  # this call's last checkpoint
        self._first = first
        self._hold = False
        self._old = {}
        self._outer: Signals | None = None

    def _handler(self, signum, frame):
        first = self.terminated is None and self.stopped is None
        if first and signum == signal.SIGINT and not self.requested:
            self.requested = True
            print(f"\ninterrupt: {self._first} (Ctrl-C again to stop at once)", file=sys.stderr, flush=True)
            return
        if first and signum == signal.SIGTERM and self.grace > 0 and self.looping:
            self.terminated = time.perf_counter()
            self.stopped = self._grace_stop()
            if self.stopped is None:
                print(f"\nSIGTERM: finishing the chunk in flight and checkpointing within the {self.grace:g} s grace "
                      f"(a second signal stops at once)", file=sys.stderr, flush=True)
                return
        else:
            self.stopped = self.stopped or Stopped(signum)
        if not self._hold:
            raise self.stopped

    def _grace_stop(self) -> Stopped | None:
        """The ``Stopped`` of a SIGTERM whose grace cannot take the chunk in flight to its end and checkpoint (the
        class docstring's estimate), or None (no SIGTERM with a grace, no chunk in flight, or it fits)."""
        if self.terminated is None or self.chunk_started is None:
            return None
        now = time.perf_counter()
        left = self.terminated + self.grace - now
        needs = max(statistics.median(self.chunk_seconds) - (now - self.chunk_started), 0.0) \
            if self.chunk_seconds else 0.0
        save = self.save_seconds or 0.0
        if needs + save <= left:
            return None
        return Stopped(signal.SIGTERM, f" ({self.grace:g} s grace, {max(left, 0.0):.1f} s of it left: the chunk in "
                                       f"flight needs about {needs:.1f} s more and a checkpoint {save:.1f} s)")

    def __enter__(self):
        for signum in (signal.SIGINT, signal.SIGTERM):
            self._old[signum] = signal.signal(signum, self._handler)
        outer = getattr(self._old[signal.SIGINT], "__self__", None)
        self._outer = outer if isinstance(outer, Signals) else None
        if self._outer is not None:
            self.requested, self.stopped = self._outer.requested, self._outer.stopped
        return self

    def __exit__(self, *exc):
        for signum, old in self._old.items():
            signal.signal(signum, old)
        if self._outer is not None:  # a loop that a SIGTERM ended within its grace stops the outer one too
            self._outer.requested = self._outer.requested or self.requested
            self._outer.stopped = self._outer.stopped or self.stopped or (
                Stopped(signal.SIGTERM) if self.terminated is not None else None)
        return False

    @contextlib.contextmanager
    def holding(self):
        """Keeps a stop that comes inside the block (``stopped``) instead of raising it there; ``check`` after
        the block raises it."""
        self._hold = True
        try:
            yield self
        finally:
            self._hold = False

    def check(self) -> None:
        """Raises the ``Stopped`` a handler raised where it was dropped, if any, or that of a SIGTERM whose grace can no
        longer take the chunk in flight to its end and checkpoint."""
        if self.stopped is None:
            self.stopped = self._grace_stop()
        if self.stopped is not None:
            raise self.stopped

    def call(self, fn: Callable[..., Any], *args: Any) -> Any:
        """``fn(*args)`` run in a thread of its own and waited for here in short sleeps (signal handlers run
        meanwhile). A chunk is dispatched so: JAX runs a program with host callbacks (the MuJoCo C engine's, on a
        CPU) in the thread that calls it, which would hold this one, and with it every signal, for the whole chunk.
        A stop raised here leaves the thread to end with its chunk; the process exits when it has (XLA cannot cancel
        a computation, and tearing the interpreter down under a host callback crashes it)."""
        done, finished = {}, threading.Event()

        def target():
            try:
                done["value"] = fn(*args)
            except BaseException as err:  # noqa: BLE001 - raised again in this thread
                done["error"] = err
            finally:
                finished.set()

        threading.Thread(target=target, name="metapg-chunk").start()
        # A signal interrupts the wait (its handler runs here); the timeout is the grace's watch. (Not the thread's
        # join: a stop raised inside it marks the running thread as ended, and the interpreter's exit then crashes.)
        while not finished.wait(0.25):
            self.check()
        if "error" in done:
            raise done["error"]
        return done["value"]

    def wait(self, tree):
        """Returns ``tree`` once every array in it is computed (signal handlers run meanwhile)."""
        import jax

        pause = 1e-3
        for leaf in jax.tree.leaves(tree):
            while hasattr(leaf, "is_ready") and not leaf.is_ready():
                time.sleep(pause)
                pause = min(2 * pause, 0.05)
                self.check()
        self.check()
        return tree


def stop_message(stop: Stopped, what: str, in_flight: int | None, num_chunks: int, checkpointed: int | None,
                 every: int, resume_command: str, restart_command: str) -> str:
    """The one line a host loop prints when ``Stopped``: what is lost and how to go on.

    Args:
      what: 'the run' or, for a sweep, 'group 2'.
      in_flight: the 1-based chunk that was running (None: stopped before the first chunk started).
      checkpointed: the chunks the last checkpoint holds (None: no checkpoint).
      resume_command / restart_command: how to continue from a checkpoint / start again without one.
    """
    who = stop.who + stop.reason
    lost = (f"chunk {in_flight} of {num_chunks} was running and is lost" if in_flight is not None
            else "no chunk had started")
    if checkpointed:
        return (f"stopped by {who}: {lost}; {what}'s last checkpoint holds {checkpointed} chunks "
                f"({checkpointed * every:,} env steps per seed); continue with: {resume_command}")
    return (f"stopped by {who}: {lost}; nothing of {what} was checkpointed, so it cannot be resumed; start "
            f"again with: {restart_command}")


def restart_command(module: str, argv: list[str] | None) -> str:
    """The command line that started this process, with ``--overwrite`` (to start again in its folder)."""
    args = list(sys.argv[1:] if argv is None else argv)
    return " ".join(["python -m", module, *args, *([] if "--overwrite" in args else ["--overwrite"])])


def run_chunks(step: Callable[[Any], tuple[Any, Any]], state: Any, *, start: int, num_chunks: int, signals: Signals,
               fetch: Callable[[Any], Any], record: Callable[[int, Any], int | None],
               save: Callable[[int, Any], None], due: Callable[[int, float], bool], interrupted: str) -> tuple[Any, int, int]:
    """Runs chunks ``start .. num_chunks - 1`` of a compiled program.

    Args:
      step: ``state -> (state, metrics)``, one chunk (the compiled program; it may donate ``state``).
      fetch: the chunk's metrics to NumPy on this host (after ``signals.wait``).
      record: ``(chunk, metrics)``: writes what the caller keeps of a chunk and tells its loggers (the progress
        bar too); a non-zero return stops the loop with that status before the chunk is checkpointed (the NaN
        guard's 3).
      save: ``(chunks_done, state)``: a checkpoint; called after the last chunk, on a first Ctrl-C, on a SIGTERM
        within its grace and when ``due(chunks run in this call, seconds since the last checkpoint)`` says so.
      interrupted: what follows "checkpointed after chunk N of M" in the line a first Ctrl-C or a SIGTERM within
        its grace prints (where, and the command that continues).

    Returns: (the state, the status: 0, 130 after a first Ctrl-C, 143 after a SIGTERM within its grace (also after
    the last chunk: the caller's end, e.g. a run's summary, is left to the resume), or ``record``'s, the chunks
    run). A second Ctrl-C, or a SIGTERM without a grace or whose grace cannot be met, raises ``Stopped``
    (``signals.in_flight`` names the chunk that was running)."""
    status, chunks_run = 0, 0
    last_save = time.perf_counter()

    def checkpoint(chunks_done: int) -> None:
        nonlocal last_save
        t = time.perf_counter()
        save(chunks_done, state)
        last_save = time.perf_counter()
        signals.save_seconds = last_save - t

    signals.looping = True
    try:
        for chunk in range(start, num_chunks):
            signals.in_flight = chunk + 1
            started = signals.chunk_started = time.perf_counter()
            state, metrics = signals.call(step, state)
            metrics = fetch(signals.wait(metrics))
            chunks_run += 1
            signals.chunk_started = None  # it has ended: a SIGTERM from here on checkpoints it
            status = record(chunk, metrics) or 0
            signals.chunk_seconds.append(time.perf_counter() - started)
            if status:
                break
            last = chunk + 1 == num_chunks
            saved = last or signals.requested or signals.terminated is not None or due(
                chunk + 1 - start, time.perf_counter() - last_save)
            if saved:
                checkpoint(chunk + 1)
            if signals.terminated is not None:  # a SIGTERM within its grace, also one that came during the save
                if not saved:
                    checkpoint(chunk + 1)
                print(f"\nstopped by SIGTERM after {time.perf_counter() - signals.terminated:.1f} s of its "
                      f"{signals.grace:g} s grace: checkpointed after chunk {chunk + 1} of {num_chunks}{interrupted}",
                      file=sys.stderr, flush=True)
                status = 143
                break
            if signals.requested and not last:
                print(f"\ninterrupted: checkpointed after chunk {chunk + 1} of {num_chunks}{interrupted}",
                      file=sys.stderr, flush=True)
                status = 130
                break
    finally:
        signals.looping, signals.chunk_started = False, None
    return state, status, chunks_run


class ChunkLoop:
    """A command's hold on one chunk loop, from before it compiles to its last checkpoint: the signal handlers
    (``Signals``), what must be closed when the loop ends (``keep``: the checkpointer, the metric writers, the
    loggers), and the one line a stop prints.

    ``with chunk_loop:`` swallows a ``Stopped`` raised inside (while compiling or in the loop): what was kept is
    closed, the stop line is printed and ``status`` is 130 or 143. Code after the ``with`` block returns
    ``chunk_loop.status``.

    Args:
      what: 'the run', or for a sweep 'group 2'.
      checkpointed: () -> the chunks the latest checkpoint holds (None: none yet).
      resume_command / restart_command: as ``stop_message``'s.
      line: (stop, chunk in flight, checkpointed) -> a stop line of the caller's, or None for ``stop_message``'s.
      grace: the seconds a first SIGTERM leaves the loop to finish its chunk in flight and checkpoint it (``Signals``;
        0: it stops at once).
    """

    def __init__(self, what: str, checkpointed: Callable[[], int | None], num_chunks: int, every: int,
                 resume_command: str, restart_command: str,
                 line: Callable[[Stopped, int | None, int | None], str | None] | None = None,
                 grace: float = TERM_GRACE):
        check_term_grace(grace, "grace")
        self.signals = Signals(grace=grace)
        self.status = 0
        self._what, self._checkpointed, self._num_chunks, self._every = what, checkpointed, num_chunks, every
        self._resume, self._restart, self._line = resume_command, restart_command, line
        self._open: list[Any] = []

    def keep(self, thing: Any) -> Any:
        """``thing`` (anything with ``close()``) is closed when the loop ends or ``close`` is called."""
        self._open.append(thing)
        return thing

    def close(self) -> None:
        """Closes what was kept, last kept first (each once)."""
        while self._open:
            self._open.pop().close()

    def run(self, step: Callable[[Any], tuple[Any, Any]], state: Any, **kwargs: Any) -> tuple[Any, int, int]:
        """``run_chunks`` with this loop's signals and chunk count (the other arguments are its)."""
        return run_chunks(step, state, num_chunks=self._num_chunks, signals=self.signals, **kwargs)

    def __enter__(self) -> ChunkLoop:
        self.signals.__enter__()
        return self

    def __exit__(self, typ, err, tb) -> bool:
        try:
            self.close()
        finally:
            self.signals.__exit__(typ, err, tb)
        if not isinstance(err, Stopped):
            return False
        checkpointed = self._checkpointed()
        text = self._line(err, self.signals.in_flight, checkpointed) if self._line else None
        print("\n" + (text or stop_message(err, self._what, self.signals.in_flight, self._num_chunks, checkpointed,
                                           self._every, self._resume, self._restart)), file=sys.stderr, flush=True)
        self.status = err.status
        return True

