"""Several processes through JAX's distributed runtime, on one machine: ``experiments.run`` started as two
CPU processes on 127.0.0.1 (JAX_COORDINATOR_ADDRESS, JAX_NUM_PROCESSES, JAX_PROCESS_ID, as on a cluster;
one CPU device each), each owning its shard of the seed axis.

What holds (tested here, by one job killed with SIGKILL and started again with ``--resume``): the
checkpoints the processes write together restore; process 0 alone writes the outputs, which cover every
seed; the numbers are those of one uninterrupted process with as many devices as the job has, bit for
bit (each device holds one seed's shard either way; one process on one device gives them up to float32
round-off, as XLA compiles a batch of 2 seeds differently from a batch of 1: ``tests/test_longrun.py``).
A seed count the processes' devices do not divide is refused before anything compiles.
"""

import json
import os
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest

from tests import xla_flags
from tests.helpers import tiny_argv

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TINY = [*tiny_argv("ddpg"), "--steps=1200", "--checkpoint-every=1"]
TIMEOUT = 600


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _env(**extra) -> dict:
    # JAX's own settings are the job's, but for the session's compile cache (conftest.py): the killed and
    # the resumed job load the program the first job compiled.
    keep = ("JAX_COMPILATION_CACHE_DIR", "JAX_ENABLE_COMPILATION_CACHE", "JAX_COMPILATION_CACHE_MAX_SIZE")
    env = {k: v for k, v in os.environ.items() if k in keep or (not k.startswith("JAX_") and k != "XLA_FLAGS")}
    env.update({"PYTHONPATH": ROOT, "JAX_PLATFORMS": "cpu", "XLA_FLAGS": xla_flags(), **extra})
    return env


def _start_job(argv, tmp_path, tag, processes=2):
    port = _free_port()
    procs = []
    for i in range(processes):
        log = open(tmp_path / f"{tag}-{i}.log", "w")
        env = _env(JAX_COORDINATOR_ADDRESS=f"127.0.0.1:{port}", JAX_NUM_PROCESSES=str(processes),
                   JAX_PROCESS_ID=str(i))
        procs.append(subprocess.Popen([sys.executable, "-u", "-m", "experiments.run", *argv], cwd=ROOT, env=env,
                                      stdout=log, stderr=subprocess.STDOUT))
    return procs


def _wait(procs, tmp_path, tag):
    codes = []
    for p in procs:
        try:
            codes.append(p.wait(timeout=TIMEOUT))
        except subprocess.TimeoutExpired:
            for q in procs:
                q.kill()
            raise AssertionError(f"{tag} hung: " + (tmp_path / f"{tag}-0.log").read_text()[-3000:])
    logs = [(tmp_path / f"{tag}-{i}.log").read_text() for i in range(len(procs))]
    return codes, logs


def _rows(out):
    return [json.loads(line) for line in open(os.path.join(out, "metrics.jsonl"))]


def _numbers(out):
    return [(r["seed"], r["chunk"], r["env_steps"], r["eval_return"], r["critic_loss"]) for r in _rows(out)]


def _policy(out):
    with np.load(os.path.join(out, "policy.npz")) as p:
        return {k: p[k] for k in p.files}


@pytest.mark.slow
def test_a_two_process_job_killed_mid_run_resumes_to_the_numbers_of_one_process_with_two_devices(tmp_path):
    """The job is killed (SIGKILL, process 1 first) once two checkpoints are written and started again with
    ``--resume``; its outputs, written by process 0 alone and covering every seed, equal bit for bit those
    of one uninterrupted process with two devices. (One process with two devices runs beside it.)"""
    reference = str(tmp_path / "two-devices")
    env = _env(XLA_FLAGS=xla_flags("--xla_force_host_platform_device_count=2"))
    single = subprocess.Popen([sys.executable, "-m", "experiments.run", *TINY, "--out", reference], cwd=ROOT,
                              env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    out = str(tmp_path / "job")
    procs = _start_job([*TINY, "--out", out], tmp_path, "killed")
    deadline = time.time() + TIMEOUT
    checkpoints = os.path.join(out, "checkpoints")
    while time.time() < deadline:  # wait for the second checkpoint, then kill process 1 mid-run
        steps = [d for d in os.listdir(checkpoints) if d.isdigit()] if os.path.isdir(checkpoints) else []
        if len(steps) >= 2 or any(p.poll() is not None for p in procs):
            break
        time.sleep(0.2)
    assert all(p.poll() is None for p in procs), "the job ended before it could be killed: " + \
        (tmp_path / "killed-0.log").read_text()[-3000:]
    assert "on 2 cpu device(s)" in (tmp_path / "killed-0.log").read_text()  # the job's devices
    procs[1].send_signal(signal.SIGKILL)
    procs[0].send_signal(signal.SIGKILL)  # the scheduler tears the job down
    for p in procs:
        p.wait(timeout=60)
    assert not os.path.exists(os.path.join(out, "summary.json"))
    codes, logs = _wait(_start_job(["--quiet", "--no-plot", "--checkpoint-every=1", "--resume", out], tmp_path,
                                   "resumed"), tmp_path, "resumed")
    assert codes == [0, 0], logs
    assert "resumed after" in logs[0] and "final return" in logs[0]
    assert "final return" not in logs[1]  # process 1 trains its shard and writes nothing
    # the session's compile cache is off for a job of several CPU processes (metapg_jax/host/compile_cache.py):
    # with it, process 0 loaded the first job's program, process 1 compiled its own, and the two hung
    assert all("compile cache off: several processes on CPU" in log for log in logs)
    rows = _rows(out)
    assert sorted((r["seed"], r["chunk"]) for r in rows) == [(s, c) for s in range(2) for c in range(4)]
    summary = json.load(open(os.path.join(out, "summary.json")))
    assert summary["num_seeds"] == 2 and len(summary["final_return_per_seed"]) == 2
    assert len(json.load(open(os.path.join(out, "config.json")))["devices"]) == 2  # the job's devices

    _, err = single.communicate(timeout=TIMEOUT)
    assert single.returncode == 0, err[-3000:]
    assert _numbers(out) == _numbers(reference)            # bit for bit
    for k, v in _policy(out).items():
        np.testing.assert_array_equal(v, _policy(reference)[k])


def test_seeds_that_the_processes_devices_do_not_divide_are_refused_before_compiling(tmp_path):
    argv = [*TINY, "--seeds=3", "--out", str(tmp_path / "odd")]
    codes, logs = _wait(_start_job(argv, tmp_path, "odd"), tmp_path, "odd")
    assert codes == [2, 2]
    assert "--seeds=3 is not a multiple of the 2 devices" in logs[0]
    assert not os.path.exists(tmp_path / "odd" / "config.json")
