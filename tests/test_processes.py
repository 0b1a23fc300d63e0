"""metapg_jax.host.processes: jax.distributed from the environment (the multi-process run itself is
tests/test_multiprocess.py)."""

import pytest

from experiments import run
from metapg_jax.host.processes import maybe_initialize_distributed


def test_distributed_initialisation_reads_the_coordinator_variables(monkeypatch, capsys):
    import jax

    calls = []
    monkeypatch.setattr(jax.distributed, "initialize", lambda **kw: calls.append(kw))
    monkeypatch.setattr(jax.distributed, "is_initialized", lambda: False)
    for var in ("JAX_COORDINATOR_ADDRESS", "JAX_NUM_PROCESSES", "JAX_PROCESS_ID"):
        monkeypatch.delenv(var, raising=False)
    maybe_initialize_distributed()
    assert calls == []                                   # one process: nothing to initialise
    monkeypatch.setenv("JAX_COORDINATOR_ADDRESS", "10.0.0.1:1234")
    maybe_initialize_distributed()                  # SLURM / Open MPI: JAX reads the rest itself
    monkeypatch.setenv("JAX_NUM_PROCESSES", "4")
    monkeypatch.setenv("JAX_PROCESS_ID", "2")
    maybe_initialize_distributed()
    assert calls == [{}, {"num_processes": 4, "process_id": 2}]
    monkeypatch.setenv("JAX_PROCESS_ID", "two")
    with pytest.raises(ValueError, match="JAX_PROCESS_ID must be a non-negative integer"):
        maybe_initialize_distributed()
    assert run.main(["--env=pendulum", "--steps=300"]) == 2  # one error line, before anything compiles
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["error: JAX_PROCESS_ID must be a non-negative integer, got 'two'"]
    # Initialised already (reproduce runs every cell in one process): not again.
    monkeypatch.setattr(jax.distributed, "is_initialized", lambda: True)
    monkeypatch.setenv("JAX_PROCESS_ID", "2")
    maybe_initialize_distributed()
    assert len(calls) == 2
