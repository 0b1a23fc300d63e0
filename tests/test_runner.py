"""The shared host loop (metapg_jax/host/runner.py): the chunk loop's order of things and its checkpoint cadence,
signals, the stop line and the ChunkLoop that holds one loop. Whole runs stopped and resumed: tests/test_longrun.py,
test_physics.py, test_sweep.py."""

import signal

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
