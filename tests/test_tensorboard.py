"""experiments.run --tensorboard: per-seed event files hold exactly the numbers of metrics.jsonl and
cycles.jsonl; a resume appends without duplicates; a missing extra fails fast with one line."""

import json
import os
import struct
import sys

import numpy as np
import pytest

from experiments import run
from metapg_jax import strategy
from metapg_jax.host import tb_events
from metapg_jax.host.checkpoint import Checkpointer
from tests.helpers import tiny_argv

# A tiny Pendulum Meta run: cycles of 50 + 100 env steps, two per 300-step chunk.
STEPS_PER_CYCLE = 150
TINY = [*tiny_argv("meta"), "--checkpoint-every=1", "--tensorboard"]
NOT_SCALARS = ("seed", "chunk", "cycle", "env_steps")


def read_events(folder):
    """{tag: [(step, value), ...]} from the TFRecord event files of one run folder, checking every CRC
    (independent of metapg_jax.host.tb_events' own reader; tensorboard itself is not installed)."""
    from tensorboardX.proto import event_pb2
    from tensorboardX.record_writer import masked_crc32c

    scalars, versions = {}, []
    for name in sorted(os.listdir(folder)):
        assert ".tfevents." in name, name
        with open(os.path.join(folder, name), "rb") as f:
            data = f.read()
        pos = 0
        while pos < len(data):
            header = data[pos:pos + 8]
            (length,) = struct.unpack("<Q", header)
            assert struct.unpack("<I", data[pos + 8:pos + 12])[0] == masked_crc32c(header)
            payload = data[pos + 12:pos + 12 + length]
            assert struct.unpack("<I", data[pos + 12 + length:pos + 16 + length])[0] == masked_crc32c(payload)
            pos += 16 + length
            event = event_pb2.Event.FromString(payload)
            if event.file_version:
                versions.append(event.file_version)
            for value in event.summary.value:
                scalars.setdefault(value.tag, []).append((event.step, value.simple_value))
    assert versions and set(versions) == {"brain.Event:2"}  # every file starts with its version record
    return scalars


def _jsonl(path):
    return [json.loads(line) for line in open(path)]


def _expected(rows, step, prefix=""):
    """{tag: [(step, float32 value), ...]} as the event files should hold them (float32: the format's scalar)."""
    out = {}
    for r in sorted(rows, key=step):
        for k, v in r.items():
            if k not in NOT_SCALARS and isinstance(v, (int, float)) and not isinstance(v, bool):
                out.setdefault(prefix + k, []).append((step(r), float(np.float32(v))))
    return out


def assert_events_match_jsonl(out, num_seeds, chunks):
    metrics, cycles = _jsonl(os.path.join(out, "metrics.jsonl")), _jsonl(os.path.join(out, "cycles.jsonl"))
    assert sorted(os.listdir(os.path.join(out, "tensorboard"))) == [f"seed_{i}" for i in range(num_seeds)]
    for seed in range(num_seeds):
        events = read_events(os.path.join(out, "tensorboard", f"seed_{seed}"))
        mine = [r for r in metrics if r["seed"] == seed]
        steps = [300 * (c + 1) for c in range(chunks)]
        assert [r["env_steps"] for r in mine] == steps
        # The evaluation return at each env step, exactly (it is a float32 in the program).
        assert events["eval_return"] == [(r["env_steps"], r["eval_return"]) for r in mine]
        teacher = {k: v for k, v in events.items() if k.startswith("meta/")}
        assert events.keys() - teacher.keys() >= {"eval_return", "critic_loss", "meta_reward", "updates"}
        want = _expected(mine, lambda r: r["env_steps"])
        assert {k: v for k, v in events.items() if k not in teacher} == want  # every number, once, in order
        # The teacher's per-cycle metrics, at the env steps stored by the end of each cycle.
        mine_cycles = [r for r in cycles if r["seed"] == seed]
        assert [r["cycle"] for r in mine_cycles] == list(range(chunks * 300 // STEPS_PER_CYCLE))
        # (a metric that is NaN in every row, written null, has no events: the paired spreads of an unpaired run)
        assert set(teacher) == {f"meta/{k}" for k in strategy.explorer("meta").cycle_metrics
                                if any(r.get(k) is not None for r in mine_cycles)}
        assert {"meta/meta_reward", "meta/teacher_log_std"} <= set(teacher)
        assert teacher == _expected(mine_cycles, lambda r: (r["cycle"] + 1) * STEPS_PER_CYCLE, "meta/")
        assert [s for s, _ in teacher["meta/meta_reward"]][1::2] == steps  # a chunk's last cycle ends at its eval


@pytest.mark.slow
def test_tensorboard_holds_the_jsonl_numbers_per_seed_and_a_resume_appends_once(tmp_path):
    pytest.importorskip("tensorboardX")
    out = str(tmp_path / "run")
    # (The resume loads the program the first call compiled from the pytest run's compile cache, conftest.py.)
    assert run.main(TINY + ["--steps=600", "--out", out]) == 0
    assert_events_match_jsonl(out, num_seeds=2, chunks=2)
    stored = json.load(open(os.path.join(out, "config.json")))
    assert "tensorboard" not in stored["run_args"]  # output only: a resume may add or leave it out
    # As after a kill: the last checkpoint is gone, so the resume runs chunk 2 again, whose events
    # (and rows) were written already.
    ck = Checkpointer(os.path.join(out, "checkpoints"))
    assert ck.steps() == [1, 2]
    ck.manager.delete(2)
    ck.close()
    assert run.main(["--resume", out, "--quiet", "--no-plot", "--tensorboard"]) == 0
    assert_events_match_jsonl(out, num_seeds=2, chunks=2)  # chunk 2 once, the resumed call's numbers
    for seed in range(2):  # the same folders, a second event file each
        assert len(os.listdir(os.path.join(out, "tensorboard", f"seed_{seed}"))) == 2


def _row(seed, chunk):
    return {"seed": seed, "chunk": chunk, "env_steps": 300 * (chunk + 1), "eval_return": chunk + 0.5 * seed,
            "train_return": None, "wall_time": 1.25, "note": "text", "flag": True}


def _cycle(seed, cycle):
    return {"seed": seed, "cycle": cycle, "meta_reward": 0.25 * cycle - seed, "r_hat_pi": None}


def test_a_resume_drops_events_past_the_checkpoint_and_writes_the_rows_they_lack(tmp_path):
    pytest.importorskip("tensorboardX")
    rows = [_row(s, c) for c in range(4) for s in range(2)]        # 4 chunks of 2 seeds
    cycles = [_cycle(s, k) for k in range(8) for s in range(2)]    # 2 cycles a chunk

    def check(folder, chunks):
        for seed in range(2):
            events = read_events(os.path.join(folder, f"seed_{seed}"))
            assert set(events) == {"eval_return", "wall_time", "cycle/meta_reward"}  # None, str, bool skipped
            assert events["eval_return"] == [(300 * (c + 1), c + 0.5 * seed) for c in range(chunks)]
            assert events["cycle/meta_reward"] == [((k + 1) * STEPS_PER_CYCLE, 0.25 * k - seed)
                                                     for k in range(2 * chunks)]
            assert tb_events.read_tensorboard_scalars(os.path.join(folder, f"seed_{seed}")) == events

    # Killed after writing chunk 2 but before checkpointing it: the resume (after chunk 1) drops chunk 2's
    # events, and then writes chunks 2-3 again as they come.
    killed = str(tmp_path / "killed")
    w = tb_events.TensorBoardWriter(killed, STEPS_PER_CYCLE)
    w.write(rows[:4], cycles[:8])
    w.write(rows[4:6], cycles[8:12])
    w.close()
    w = tb_events.TensorBoardWriter(killed, STEPS_PER_CYCLE)
    w.resume(rows[:4], cycles[:8], done_steps=600)
    check(killed, chunks=2)
    w.write(rows[4:6], cycles[8:12])
    w.write(rows[6:], cycles[12:])
    w.close()
    check(killed, chunks=4)
    # Resumed without --tensorboard in between (chunks 2-3 have rows, no events): the gap is filled first.
    gap = str(tmp_path / "gap")
    w = tb_events.TensorBoardWriter(gap, STEPS_PER_CYCLE)
    w.write(rows[:4], cycles[:8])
    w.close()
    w = tb_events.TensorBoardWriter(gap, STEPS_PER_CYCLE)
    w.resume(rows, cycles, done_steps=1200)
    w.close()
    check(gap, chunks=4)
    # A run that never had --tensorboard: every finished row.
    never = str(tmp_path / "never")
    w = tb_events.TensorBoardWriter(never, STEPS_PER_CYCLE)
    w.resume(rows[:4], cycles[:8], done_steps=600)
    w.close()
    check(never, chunks=2)
    # Written before cycle rows took their explorer's name ('teacher/'): resumed, nothing is written twice.
    old = str(tmp_path / "old")
    w = tb_events.TensorBoardWriter(old, STEPS_PER_CYCLE, cycle_prefix="teacher/")
    w.write(rows[:4], cycles[:8])
    w.close()
    w = tb_events.TensorBoardWriter(old, STEPS_PER_CYCLE)
    w.resume(rows[:4], cycles[:8], done_steps=600)
    w.close()
    events = read_events(os.path.join(old, "seed_0"))
    assert "cycle/meta_reward" not in events and len(events["teacher/meta_reward"]) == 4
    with pytest.raises(ValueError, match="one name and a slash"):
        tb_events.TensorBoardWriter(old, STEPS_PER_CYCLE, cycle_prefix="a/b/")


def test_missing_tensorboardx_exits_2_with_one_line_before_writing(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "tensorboardX", None)  # `import tensorboardX` raises ImportError
    out = tmp_path / "run"
    assert run.main(["--env=pendulum", "--method=meta", "--steps=300", "--tensorboard", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: --tensorboard needs tensorboardX") \
        and 'pip install -e ".[tensorboard]"' in err[0], err
    assert not out.exists()
