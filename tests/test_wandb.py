"""experiments.run --wandb, offline (no network): one W&B run per seed holds the run's config and exactly the numbers
of metrics.jsonl and cycles.jsonl at env steps; a resume continues the same W&B runs and logs each chunk once; a
missing extra fails fast with one line."""

import glob
import json
import os
import struct
import sys
import zlib

import pytest

from experiments import run
from metapg_jax.config import from_dict
from metapg_jax.host.checkpoint import Checkpointer
from metapg_jax.host.metric_rows import scalars
from tests.helpers import TINY_BUFFER, TINY_RUN

# Shares its programs with tests/test_longrun.py (a fixed replay capacity: any budget, one program).
TINY = [*TINY_RUN, *TINY_BUFFER, "--checkpoint-every=1"]


@pytest.fixture
def offline(tmp_path, monkeypatch):
    """W&B offline, its files under tmp_path/wandb-files; W&B's process-wide setup is reset afterwards (it keeps
    the environment it first read)."""
    wandb = pytest.importorskip("wandb")
    folder = tmp_path / "wandb-files"
    folder.mkdir()
    monkeypatch.setenv("WANDB_MODE", "offline")
    monkeypatch.setenv("WANDB_DIR", str(folder))
    wandb.teardown()
    yield str(folder)
    wandb.teardown()


def wandb_records(path):
    """The records of a W&B transaction log (``run-<id>.wandb``: LevelDB's log format, 32 KiB blocks of records
    with a CRC-32 each, after a 7-byte header; W&B's ``Record`` protobufs), checking every CRC."""
    from wandb.proto import wandb_internal_pb2

    data = open(path, "rb").read()
    assert data[:4] == b":W&B", data[:7]
    pos, records, parts = 7, [], []
    while pos + 7 <= len(data):
        if 32768 - pos % 32768 < 7:  # a block's tail too short for a header is padding
            pos += 32768 - pos % 32768
            continue
        crc, length, kind = struct.unpack("<IHB", data[pos:pos + 7])
        payload = data[pos + 7:pos + 7 + length]
        pos += 7 + length
        if kind == 0 and length == 0:
            continue
        assert zlib.crc32(payload, zlib.crc32(bytes([kind]))) == crc
        parts.append(payload)
        if kind in (1, 4):  # a whole record, or the last part of one
            records.append(wandb_internal_pb2.Record.FromString(b"".join(parts)))
            parts = []
    return records


def offline_runs(folder):
    """{run id: [(the run record, {step: {metric: value}}, {summary key: value}, exit code), ...]}, one entry per
    offline run folder (a resumed run has one per call), in the order they were written. W&B's service process is
    shut down first: it may still be writing the files of runs that have finished."""
    import wandb

    wandb.teardown()
    found = {}
    for path in sorted(glob.glob(os.path.join(folder, "wandb", "offline-run-*", "*.wandb"))):
        run_record, history, summary, exit_code = None, {}, {}, None
        for r in wandb_records(path):
            kind = r.WhichOneof("record_type")
            if kind == "run":
                run_record = r.run
            elif kind == "history":
                items = {"/".join(i.nested_key) or i.key: json.loads(i.value_json) for i in r.history.item}
                assert r.history.step.num not in history
                history[r.history.step.num] = {k: v for k, v in items.items() if not k.startswith("_")}
            elif kind == "summary":
                summary.update({"/".join(u.nested_key) or u.key: json.loads(u.value_json) for u in r.summary.update})
            elif kind == "exit":
                exit_code = r.exit.exit_code
        found.setdefault(run_record.run_id, []).append((run_record, history, summary, exit_code))
    return found


def expected_history(out, seed):
    """{env step: {metric: value}} of one seed as the W&B run should hold it: each metrics row's numbers at its env
    steps, each cycle row's as meta/<name> at the env steps stored by the end of its cycle."""
    steps_per_cycle = from_dict(json.load(open(os.path.join(out, "config.json")))["config"]).steps_per_cycle
    want = {}
    for line in open(os.path.join(out, "cycles.jsonl")):
        row = json.loads(line)
        if row["seed"] == seed:
            want.setdefault((row["cycle"] + 1) * steps_per_cycle, {}).update(
                {f"meta/{k}": v for k, v in scalars(row).items()})
    for line in open(os.path.join(out, "metrics.jsonl")):
        row = json.loads(line)
        if row["seed"] == seed:
            want.setdefault(row["env_steps"], {}).update(scalars(row))
    return want


def merged(calls, drop=("wall_time", "chunk_seconds")):
    """The history of a W&B run over its calls, timings left out (a repeated chunk has new ones)."""
    history = {}
    for _, h, _, _ in calls:
        assert not set(h) & set(history), "a step was logged twice"
        history.update({step: {k: v for k, v in row.items() if k not in drop} for step, row in h.items()})
    return history


@pytest.mark.slow
def test_a_run_logs_one_wandb_run_per_seed_and_a_resume_continues_them(offline, tmp_path, capsys):
    out = str(tmp_path / "run")
    assert run.main([*TINY, "--steps=600", "--out", out, "--wandb", "--wandb-group", "tiny"]) == 0
    assert "W&B: 2 runs, one per seed, in project metapg-jax, group tiny, offline" in capsys.readouterr().out
    stored = json.load(open(os.path.join(out, "wandb.json")))
    ids = stored["runs"]
    assert len(ids) == 2 and stored["logged_chunks"] == 2 and stored["group"] == "tiny"
    runs = offline_runs(offline)
    assert sorted(runs) == sorted(ids)
    config = json.load(open(os.path.join(out, "config.json")))
    for seed, run_id in enumerate(ids):
        [(record, history, summary, exit_code)] = runs[run_id]
        assert (record.project, record.run_group, record.display_name) == ("metapg-jax", "tiny", f"run-seed{seed}")
        logged = {u.key: json.loads(u.value_json) for u in record.config.update}
        assert {k: logged[k] for k in config["config"]} == config["config"]
        assert logged["run_args"] == config["run_args"] and logged["seed_index"] == seed
        assert history == expected_history(out, seed) and sorted(history) == [300, 600]
        final = json.load(open(os.path.join(out, "summary.json")))
        assert summary["final_return"] == final["final_return_per_seed"][seed] and exit_code == 0
        assert summary["final_return_mean"] == final["final_return_mean"]

    # As after a kill: the last checkpoint is gone; the resume extends the run to 900 steps. It trains chunk 2
    # again (W&B has it: not logged twice) and then chunk 3, into the same W&B runs.
    ck = Checkpointer(os.path.join(out, "checkpoints"))
    ck.manager.delete(2)
    ck.close()
    assert run.main(["--resume", out, "--steps=900", "--quiet", "--no-plot", "--wandb"]) == 0
    runs = offline_runs(offline)
    assert sorted(runs) == sorted(ids) and json.load(open(os.path.join(out, "wandb.json")))["logged_chunks"] == 3
    for seed, run_id in enumerate(ids):
        calls = runs[run_id]
        assert len(calls) == 2 and calls[1][0].resume and calls[1][0].run_group == "tiny"  # the stored group
        assert sorted(calls[1][1]) == [900]
        assert merged(calls) == merged([(None, expected_history(out, seed), None, None)])


@pytest.mark.slow
def test_a_run_without_wandb_resumed_with_it_logs_every_finished_chunk(offline, tmp_path):
    out = str(tmp_path / "run")
    assert run.main([*TINY, "--steps=600", "--out", out]) == 0
    ck = Checkpointer(os.path.join(out, "checkpoints"))
    ck.manager.delete(2)
    ck.close()
    assert run.main(["--resume", out, "--quiet", "--no-plot", "--wandb", "--wandb-project", "elsewhere"]) == 0
    runs = offline_runs(offline)
    assert len(runs) == 2
    for seed, run_id in enumerate(json.load(open(os.path.join(out, "wandb.json")))["runs"]):
        [(record, history, _, _)] = runs[run_id]
        assert (record.project, record.run_group) == ("elsewhere", "run")  # the folder's name by default
        assert history == expected_history(out, seed)  # chunk 1 from metrics.jsonl, chunk 2 as it came


@pytest.mark.parametrize("argv, message", [
    (["--wandb"], 'error: --wandb needs wandb: pip install -e ".[wandb]"'),
    (["--wandb-project=x"], "error: --wandb-project, --wandb-entity and --wandb-group need --wandb"),
])
def test_wandb_options_are_checked_before_anything_is_written(argv, message, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "wandb", None)  # `import wandb` raises ImportError
    out = tmp_path / "run"
    assert run.main(["--env=pendulum", "--steps=300", *argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(message), err
    assert not out.exists()
