"""The shared host loop (metapg_jax/host/runner.py): the chunk loop's order of things and its checkpoint cadence,
signals (a SIGTERM's grace: the chunk in flight finished and checkpointed where it fits, else a stop at once, on fake
chunks with set durations), the stop line and the ChunkLoop that holds one loop. Whole runs stopped and resumed: tests/test_longrun.py,
test_physics.py, test_sweep.py."""

import re
import signal
import time

import numpy as np
import pytest

from metapg_jax.host import runner


def _chunk(state):
    """A fake compiled chunk: the state counts chunks; the metrics are what a real chunk returns to the host."""
    return state + 1, {"env_steps": np.full(2, 10 * (state + 1)), "eval_return": np.zeros((2, 3))}


def test_the_chunk_loop_records_every_chunk_saves_on_its_cadence_and_at_the_end():
    recorded, saved = [], []
    state, status, chunks_run = runner.run_chunks(
        _chunk, 2, start=2, num_chunks=7, signals=runner.Signals(), fetch=lambda m: m,
        record=lambda chunk, m: recorded.append((chunk, int(m["env_steps"][0]))),
        save=lambda done, s: saved.append((done, s)), due=lambda run_here, since: run_here % 2 == 0, interrupted="")
    assert (state, status, chunks_run) == (7, 0, 5)
    assert recorded == [(2, 30), (3, 40), (4, 50), (5, 60), (6, 70)]
    assert saved == [(4, 4), (6, 6), (7, 7)]  # every 2 chunks run in this call, and the last


def test_a_status_from_record_stops_before_the_chunk_is_saved_and_a_first_ctrl_c_after_it(capsys):
    saved = []
    kw = dict(start=0, num_chunks=5, fetch=lambda m: m, due=lambda *_: False,
              save=lambda done, s: saved.append(done), interrupted="; continue with: RESUME")
    _, status, chunks_run = runner.run_chunks(_chunk, 0, signals=runner.Signals(),
                                              record=lambda chunk, m: 3 if chunk == 1 else None, **kw)
    assert (status, chunks_run, saved) == (3, 2, [])  # the NaN guard's stop: the bad chunk is not checkpointed
    signals = runner.Signals()
    signals.requested = True  # a first Ctrl-C during the first chunk
    state, status, chunks_run = runner.run_chunks(_chunk, 0, signals=signals, record=lambda *_: None, **kw)
    assert (state, status, chunks_run, saved) == (1, 130, 1, [1])
    assert "interrupted: checkpointed after chunk 1 of 5; continue with: RESUME" in capsys.readouterr().err


def test_the_stop_line_after_a_checkpoint_names_the_resume():
    import signal

    line = runner.stop_message(runner.Stopped(signal.SIGINT), "the run", 3, 10, 2, 9000, "RESUME", "RESTART")
    assert line == ("stopped by Ctrl-C: chunk 3 of 10 was running and is lost; the run's last checkpoint holds 2 "
                    "chunks (18,000 env steps per seed); continue with: RESUME")
    assert runner.Stopped(signal.SIGINT).status == 130 and runner.Stopped(signal.SIGTERM).status == 143


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")  # the drop this test makes
def test_a_stop_that_python_dropped_is_raised_by_the_next_wait():
    """A SIGTERM handled inside a garbage-collection callback: Python prints and drops the handler's
    exception there (seen in this suite: the run then trained on and exited 0); the loop's next ``wait``
    raises it."""
    import gc
    import signal

    import numpy as np

    signals = runner.Signals()

    class Collected:
        def __del__(self):
            signals._handler(signal.SIGTERM, None)  # raises Stopped, which Python drops here

    Collected()
    gc.collect()
    assert isinstance(signals.stopped, runner.Stopped)
    with pytest.raises(runner.Stopped, match="SIGTERM"):
        signals.wait({"x": np.zeros(2)})


def test_a_chunk_loop_closes_what_it_kept_and_turns_a_stop_into_its_line_and_status(capsys):
    """A stop raised while compiling (or in the loop) inside ``with chunk_loop``: everything kept is closed, last
    kept first, the stop line is printed with the latest checkpoint, and the status is the signal's."""
    closed = []

    class Closable:
        def __init__(self, name):
            self.name = name

        def close(self):
            closed.append(self.name)

    chunk_loop = runner.ChunkLoop("the run", lambda: 4, 10, 300, "RESUME", "RESTART")
    with chunk_loop:
        chunk_loop.keep(Closable("checkpointer"))
        chunk_loop.keep(Closable("writer"))
        raise runner.Stopped(signal.SIGTERM)
    assert chunk_loop.status == 143 and closed == ["writer", "checkpointer"]
    err = capsys.readouterr().err
    assert "stopped by SIGTERM: no chunk had started; the run's last checkpoint holds 4 chunks (1,200 env steps" in err
    assert err.rstrip().endswith("continue with: RESUME")
    # A caller's own line wins where it gives one; other errors pass through after closing.
    chunk_loop = runner.ChunkLoop("group 2", lambda: None, 10, 300, "RESUME", "RESTART", line=lambda stop, c, d: "MINE")
    with chunk_loop:
        raise runner.Stopped(signal.SIGINT)
    assert chunk_loop.status == 130 and capsys.readouterr().err.strip() == "MINE"
    chunk_loop = runner.ChunkLoop("the run", lambda: None, 10, 300, "RESUME", "RESTART")
    kept = chunk_loop.keep(Closable("progress"))
    try:
        with chunk_loop:
            raise ValueError("not a stop")
    except ValueError:
        pass
    assert closed[-1] == kept.name and chunk_loop.status == 0


@pytest.fixture
def sigint_ignored():
    """SIGINT as a shell leaves it for a job it starts in the background (``cmd &``): ignored."""
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    yield
    signal.signal(signal.SIGINT, old)


def test_a_ctrl_c_between_two_loops_is_kept_and_the_next_loop_starts_with_it(sigint_ignored, capsys):
    with runner.Signals("the grid stops before the next cell") as outer:
        signal.raise_signal(signal.SIGINT)  # between two loops, in a process started with SIGINT ignored
        assert outer.requested
        with runner.Signals() as inner:
            assert inner.requested  # a run being set up stops after its first chunk
            with pytest.raises(runner.Stopped, match="SIGINT"):
                signal.raise_signal(signal.SIGINT)  # the second Ctrl-C: at once
        assert signal.getsignal(signal.SIGINT) == outer._handler
    assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN
    assert capsys.readouterr().err.count("interrupt: the grid stops before the next cell (Ctrl-C again") == 1
    with runner.Signals() as alone:
        assert not alone.requested


def test_a_stop_held_between_loops_reaches_the_next_loop_and_one_a_loop_got_reaches_the_outer_one(capsys):
    with runner.Signals("the grid stops before the next cell") as outer:
        with outer.holding():
            with runner.Signals() as run:  # a Ctrl-C during a run's last chunk: the run itself ends normally
                signal.raise_signal(signal.SIGINT)
            assert run.requested and outer.requested  # so the grid does not start the next cell
            signal.raise_signal(signal.SIGTERM)  # while the finished cell is archived: kept, not raised
        with pytest.raises(runner.Stopped, match="SIGTERM"):
            outer.check()
        with runner.Signals() as late:  # a loop set up while the stop was held raises it at its first wait
            with pytest.raises(runner.Stopped, match="SIGTERM"):
                late.wait({"x": np.zeros(2)})
    assert "interrupt: finishing the current chunk" in capsys.readouterr().err


class _Pending:
    """A chunk's result as the host sees a dispatched JAX array: ready ``seconds`` after the chunk started. It sends
    this process the signals of ``signals`` ({seconds into the chunk: signal}) when the loop looks at it then."""

    def __init__(self, seconds: float, signals: dict):
        self.started, self.seconds, self.signals = time.perf_counter(), seconds, dict(signals)

    def is_ready(self) -> bool:
        elapsed = time.perf_counter() - self.started
        for at in sorted(self.signals):
            if elapsed >= at:
                signal.raise_signal(self.signals.pop(at))
        return elapsed >= self.seconds


def _timed_chunks(seconds, signals=None):
    """A fake compiled chunk whose chunk ``i`` (0-based, counted by the state) takes ``seconds[i]`` and sends
    ``signals[i]`` ({seconds into it: signal})."""
    signals = signals or {}

    def step(state):
        return state + 1, {"pending": _Pending(seconds[state], signals.get(state, {}))}

    return step


def _loop(signals, step, num_chunks, saved, due=lambda *_: False, save_seconds=0.0):
    def save(done, state):
        time.sleep(save_seconds)
        saved.append(done)

    return runner.run_chunks(step, 0, start=0, num_chunks=num_chunks, signals=signals, fetch=lambda m: m,
                             record=lambda *_: None, save=save, due=due, interrupted="; continue with: RESUME")


def test_a_sigterm_within_its_grace_finishes_the_chunk_in_flight_checkpoints_it_and_exits_143(capsys):
    """Chunks of 0.1 s; SIGTERM 0.02 s into the third: it ends and is checkpointed (no checkpoint before), 143; the
    loop's stop reaches the command's outer ``Signals`` (a grid's, a sweep's), so it starts nothing more."""
    saved = []
    with runner.Signals() as outer:  # a grid's or a sweep's, around the loop
        with runner.Signals(grace=2.0) as signals:
            state, status, chunks_run = _loop(signals, _timed_chunks([0.1] * 6, {2: {0.02: signal.SIGTERM}}), 6, saved)
        assert outer.stopped is not None and outer.stopped.status == 143  # so the grid does not go on
    assert (state, status, chunks_run, saved) == (3, 143, 3, [3])
    err = capsys.readouterr().err
    assert "SIGTERM: finishing the chunk in flight and checkpointing within the 2 s grace" in err
    line = err.strip().splitlines()[-1]
    assert re.fullmatch(r"stopped by SIGTERM after 0\.\d s of its 2 s grace: checkpointed after chunk 3 of 6; "
                        r"continue with: RESUME", line), line
    # One that comes after the chunk ended (while it is recorded), also in the last chunk: checkpointed, 143.
    saved = []
    with runner.Signals(grace=2.0) as signals:
        _, status, _ = runner.run_chunks(
            _timed_chunks([0.01] * 2), 0, start=0, num_chunks=2, signals=signals, fetch=lambda m: m,
            record=lambda chunk, m: signal.raise_signal(signal.SIGTERM) if chunk == 1 else None,
            save=lambda done, s: saved.append(done), due=lambda *_: False, interrupted="")
    assert (status, saved) == (143, [2])
    assert "checkpointed after chunk 2 of 2" in capsys.readouterr().err


def test_a_sigterm_whose_grace_cannot_be_met_or_without_one_stops_at_once(capsys):
    """Chunks of 0.3 s, SIGTERM 0.01 s into the third with a 0.5 s grace: the chunk's 0.29 s fit when no checkpoint
    was written yet in the call (nothing is kept for one); with a checkpoint of 0.3 s measured after the first
    chunk they do not: stopped at once, saying why. A grace of 0, a second signal, and a SIGTERM outside a loop stop
    at once."""
    chunks = [0.3] * 4
    saved = []
    with runner.Signals(grace=0.5) as signals:
        _, status, _ = _loop(signals, _timed_chunks(chunks, {2: {0.01: signal.SIGTERM}}), 4, saved)
    assert status == 143 and saved == [3]
    saved = []
    with runner.Signals(grace=0.5) as signals:
        with pytest.raises(runner.Stopped) as stop:
            _loop(signals, _timed_chunks(chunks, {2: {0.01: signal.SIGTERM}}), 4, saved,
                  due=lambda run_here, since: run_here == 1, save_seconds=0.3)
    assert stop.value.status == 143 and saved == [1] and signals.in_flight == 3
    assert re.fullmatch(r" \(0\.5 s grace, 0\.\d s of it left: the chunk in flight needs about 0\.\d s more and a "
                        r"checkpoint 0\.3 s\)", stop.value.reason), stop.value.reason
    line = runner.stop_message(stop.value, "the run", 3, 4, 1, 300, "RESUME", "RESTART")
    assert line.startswith("stopped by SIGTERM (0.5 s grace, ") and "chunk 3 of 4 was running and is lost" in line
    for grace, signals_sent in ((0.0, {0.01: signal.SIGTERM}), (5.0, {0.01: signal.SIGTERM, 0.03: signal.SIGTERM}),
                                (5.0, {0.01: signal.SIGTERM, 0.03: signal.SIGINT})):
        saved = []
        with runner.Signals(grace=grace) as signals:
            with pytest.raises(runner.Stopped) as stop:
                _loop(signals, _timed_chunks([0.1] * 3, {1: signals_sent}), 3, saved)
        assert saved == [] and signals.in_flight == 2 and stop.value.reason == "", grace
    with runner.Signals(grace=5.0):  # while a program compiles or a run is set up: no chunk to finish
        with pytest.raises(runner.Stopped, match="SIGTERM"):
            signal.raise_signal(signal.SIGTERM)


def test_a_chunk_that_overruns_its_grace_is_given_up_when_only_the_checkpoints_share_is_left():
    """A SIGTERM 0.01 s into a chunk that takes 5 s, with a 1 s grace: the loop waits for it, then stops at once
    when what is left of the grace is what a checkpoint needs (none written in the call: when the grace is over;
    one of 0.3 s: 0.3 s before), for the first chunk (nothing measured) as for one far slower than those before."""
    for chunks, at, due, save_s in (([5.0], 0, lambda *_: False, 0.0), ([0.05, 0.05, 5.0], 2, lambda *_: False, 0.0),
                                    ([0.05, 0.05, 5.0], 2, lambda run_here, since: run_here == 1, 0.3)):
        with runner.Signals(grace=1.0) as signals:
            with pytest.raises(runner.Stopped) as stop:
                _loop(signals, _timed_chunks(chunks, {at: {0.01: signal.SIGTERM}}), len(chunks), [], due, save_s)
        waited = time.perf_counter() - signals.terminated
        assert 0.95 - save_s <= waited < 1.3 - save_s and signals.in_flight == at + 1, (waited, save_s)
        assert "the chunk in flight needs about 0.0 s more" in stop.value.reason


def test_a_signal_is_handled_at_once_while_a_chunk_holds_the_thread_that_runs_it():
    """JAX runs a program with host callbacks (the C engine on a CPU) in the thread that calls it, in C, where no
    Python signal handler runs until it returns: the loop runs each chunk in a thread of its own, so the main
    thread handles a SIGTERM at once (here: a chunk that holds its thread 2 s with SIGTERM blocked in it; without
    the grace the stop comes within a fraction of a second, with it the grace is counted from the signal)."""
    import os
    import threading

    def step(state):
        assert threading.current_thread() is not threading.main_thread()
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTERM})  # as a thread inside a C call: no handler here
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(2.0)
        finally:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGTERM})
        return state + 1, {}

    for grace in (0.0, 5.0):
        t = time.perf_counter()
        with runner.Signals(grace=grace) as signals:
            if grace:
                _, status, _ = _loop(signals, step, 1, [])
                assert status == 143 and signals.terminated - t < 0.5
            else:
                with pytest.raises(runner.Stopped):
                    _loop(signals, step, 1, [])
                assert time.perf_counter() - t < 1.0


def test_a_grace_must_be_a_finite_number_of_seconds():
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="--term-grace must be a finite number of seconds >= 0"):
            runner.check_term_grace(bad)
        with pytest.raises(ValueError, match="grace must be"):
            runner.ChunkLoop("the run", lambda: None, 2, 300, "R", "S", grace=bad)
