"""Several processes: ``jax.distributed`` started from the environment, barriers, and sharded arrays gathered
to one host. Each is a no-op with one process."""

from __future__ import annotations

import os

def maybe_initialize_distributed() -> None:
    """Multi-host: ``jax.distributed.initialize()`` when JAX_COORDINATOR_ADDRESS is set.

    Set on every host JAX_COORDINATOR_ADDRESS (host:port of process 0) and, unless the processes
    were launched by SLURM's ``srun`` or Open MPI's ``mpirun`` (whose variables JAX reads itself),
    JAX_NUM_PROCESSES and JAX_PROCESS_ID; the seed axis is then sharded over the devices of all
    hosts. Without JAX_COORDINATOR_ADDRESS every process runs on its own devices only.
    """
    if not os.environ.get("JAX_COORDINATOR_ADDRESS"):
        return
    import jax

    if jax.distributed.is_initialized():  # experiments.reproduce runs many cells in one process
        return
    kwargs = {}
    for var, name in (("JAX_NUM_PROCESSES", "num_processes"), ("JAX_PROCESS_ID", "process_id")):
        value = os.environ.get(var, "").strip()
        if value:
            if not value.isdigit():
                raise ValueError(f"{var} must be a non-negative integer, got {value!r}")
            kwargs[name] = int(value)
    jax.distributed.initialize(**kwargs)


def barrier(name: str) -> None:
    """With several processes: waits until every process got here (a no-op with one)."""
    import jax

    if jax.process_count() > 1:
        from jax.experimental import multihost_utils

        multihost_utils.sync_global_devices(name)


def to_host(tree):
    """Fetches (possibly multi-host sharded) arrays to NumPy on this host."""
    import jax

    if jax.process_count() > 1:
        from jax.experimental import multihost_utils

        return multihost_utils.process_allgather(tree, tiled=True)
    return jax.device_get(tree)
