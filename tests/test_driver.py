"""The training driver called as a notebook or the grid engine calls it (metapg_jax/host/driver.py): a validated
config, the run args and a folder, no argv; its loggers see the run's life in order and exactly the rows of its
files; ``experiments.run --resume`` continues the folder it wrote; bad arguments are one-line ValueErrors."""

import json
import os
import signal

import pytest

from experiments import run
from experiments.training.args import RUN_ARGS, config_from_run_args, resolved_run_args
from metapg_jax.host import driver
from metapg_jax.host.loggers import Callback, Logger
from tests.helpers import TINY_BUFFER, TINY_RUN

# The options of tests/test_longrun.py's runs as run args (the same programs: the pytest run's compile cache).
OVERRIDES = [v for flag, v in zip(TINY_RUN + TINY_BUFFER, (TINY_RUN + TINY_BUFFER)[1:]) if flag == "--set"]


def run_args(steps):
    a = {**RUN_ARGS, "env": "pendulum", "method": "meta", "seeds": 2, "steps": steps, "overrides": OVERRIDES}
    cfg = config_from_run_args(a)
    return cfg, resolved_run_args(a, cfg)


class Recording(Logger):
    """Every call, in order (start and chunk: what they were given)."""

    def __init__(self):
        self.calls = []

    def start(self, cfg, run_args, out, resumed_from):
        self.calls.append(("start", cfg.run.total_steps, run_args["seeds"], out, resumed_from))

    def chunk(self, rows, cycles):
        self.calls.append(("chunk", rows, cycles))

    def checkpoint(self, chunks_done):
        self.calls.append(("checkpoint", chunks_done))

    def finish(self, summary):
        self.calls.append(("finish", summary))

    def close(self):
        self.calls.append(("close",))


def _jsonl(path):
    return [json.loads(line) for line in open(path)]


@pytest.mark.slow
def test_the_driver_reports_a_run_to_its_loggers_and_the_command_line_resumes_it(tmp_path):
    cfg, a = run_args(600)
    out = str(tmp_path / "run")
    logger, curve = Recording(), []
    progress = Callback(chunk=lambda rows, cycles: curve.append((rows[0]["env_steps"], len(rows))))
    assert driver.run(cfg, a, out, loggers=[logger, progress], checkpoint_every=1) == 0
    kinds = [c[0] for c in logger.calls]
    assert kinds == ["start", "chunk", "checkpoint", "chunk", "checkpoint", "finish", "close"]
    assert logger.calls[0] == ("start", 600, 2, out, 0)
    rows, cycles = _jsonl(os.path.join(out, "metrics.jsonl")), _jsonl(os.path.join(out, "cycles.jsonl"))
    assert [r for c in logger.calls if c[0] == "chunk" for r in c[1]] == rows  # what the files hold, as written
    assert [r for c in logger.calls if c[0] == "chunk" for r in c[2]] == cycles and cycles
    assert [c[1] for c in logger.calls if c[0] == "checkpoint"] == [1, 2] and curve == [(300, 2), (600, 2)]
    record = logger.calls[-2][1]  # without a finalize: the driver's record of the call
    assert record["resumed_from_chunk"] == 0 and record["train_seconds"] > 0
    assert not os.path.exists(os.path.join(out, "summary.json"))
    assert json.load(open(os.path.join(out, "config.json")))["run_args"] == a
    # A folder the driver wrote is a run folder: the command line extends it.
    assert run.main(["--resume", out, "--steps=900", "--quiet", "--no-plot"]) == 0
    assert [r["env_steps"] for r in _jsonl(os.path.join(out, "metrics.jsonl"))] == [300, 300, 600, 600, 900, 900]
    assert json.load(open(os.path.join(out, "summary.json")))["resumed_from_chunk"] == 2


def test_an_interrupted_run_closes_its_loggers_without_finishing(tmp_path):
    cfg, a = run_args(900)
    logger = Recording()
    ctrl_c = Callback(chunk=lambda rows, cycles: signal.raise_signal(signal.SIGINT))  # during the first chunk's record
    assert driver.run(cfg, a, str(tmp_path / "run"), loggers=[logger, ctrl_c]) == 130
    assert [c[0] for c in logger.calls] == ["start", "chunk", "checkpoint", "close"]  # checkpointed, then stopped


@pytest.mark.slow
def test_a_sigterm_in_the_last_chunk_checkpoints_it_exits_143_and_the_resume_only_finishes(tmp_path):
    """A SIGTERM while the last chunk is recorded: checkpointed, exit 143, the loggers closed unfinished (the summary
    is the resume's); the resume trains nothing and finishes the run."""
    cfg, a = run_args(600)
    out = str(tmp_path / "run")
    logger, seen = Recording(), []

    def sigterm_in_the_last_chunk(rows, cycles):
        seen.append(rows)
        if len(seen) == 2:
            signal.raise_signal(signal.SIGTERM)

    assert driver.run(cfg, a, out, loggers=[logger, Callback(chunk=sigterm_in_the_last_chunk)]) == 143
    assert [c[0] for c in logger.calls] == ["start", "chunk", "chunk", "checkpoint", "close"]
    assert not os.path.exists(os.path.join(out, "summary.json"))
    logger = Recording()
    assert driver.run(cfg, a, out, loggers=[logger], resume=True) == 0
    assert [c[0] for c in logger.calls] == ["start", "finish", "close"] and logger.calls[0][-1] == 2
    assert logger.calls[1][1]["resumed_from_chunk"] == 2


@pytest.mark.parametrize("kwargs, message", [
    ({"checkpoint_every": -1}, "checkpoint_every must be >= 0 and checkpoint_minutes > 0, got -1 and 5.0"),
    ({"checkpoint_minutes": 0}, "checkpoint_every must be >= 0 and checkpoint_minutes > 0, got 0 and 0"),
    ({"extend_from": 300}, "extend_from extends a stored run: it needs resume=True"),
    ({"term_grace": -1}, "term_grace must be a finite number of seconds >= 0"),
])
def test_bad_arguments_are_refused_before_anything_is_written(kwargs, message, tmp_path):
    cfg, a = run_args(600)
    with pytest.raises(ValueError, match=message):
        driver.run(cfg, a, str(tmp_path / "x"), **kwargs)
    with pytest.raises(ValueError, match="run_args needs 'seeds' and 'seed'"):
        driver.run(cfg, {"env": "pendulum"}, str(tmp_path / "x"))
    assert not (tmp_path / "x").exists()
