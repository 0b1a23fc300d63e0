"""Size checks before compile: the bytes of a training state from its shapes alone, against the memory the
host (and the accelerators) have; a run or sweep that cannot fit is refused with one line."""

from __future__ import annotations

import os

def available_host_bytes() -> int:
    """Memory this process can still take: MemAvailable (Linux), else the physical memory."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def gib(n: float) -> str:
    """Bytes in binary units, e.g. '18.7 GiB', '6.4 PiB'."""
    for power, unit in ((50, "PiB"), (40, "TiB"), (30, "GiB")):
        if n >= 2 ** power:
            return f"{n / 2 ** power:,.1f} {unit}"
    return f"{n / 2**20:,.0f} MiB"


def state_bytes(init, *args) -> int:
    """Bytes of the state ``init(*args)`` returns, from its shapes alone (``jax.eval_shape``: nothing runs,
    nothing compiles). ``args`` may be ``jax.ShapeDtypeStruct``s."""
    import jax

    return sum(x.size * x.dtype.itemsize for x in jax.tree.leaves(jax.eval_shape(init, *args)))


def check_fits(nbytes: int, what: str) -> None:
    """Raises ``ValueError`` (one line: needed vs available) when a training state of ``nbytes`` (all seeds,
    all processes) cannot fit: on a CPU the state and a checkpoint's copy of it in host memory; on an
    accelerator the state in its devices' memory (and the checkpoint's copy in host memory)."""
    import jax

    share = nbytes // jax.process_count()  # each process holds its devices' seeds
    cpu = jax.default_backend() == "cpu"
    host_needed, host_available = (2 if cpu else 1) * share, available_host_bytes()
    if host_needed > host_available:
        why = "its training state and a checkpoint's copy of it" if cpu else "a checkpoint's copy of its training state"
        raise ValueError(f"{what} needs about {gib(host_needed)} of memory ({why}); this machine has "
                         f"{gib(host_available)} available: use fewer seeds or a smaller replay buffer "
                         f"(--set run.buffer_size=N)")
    if not cpu:
        limits = [(d.memory_stats() or {}).get("bytes_limit") for d in jax.local_devices()]
        if all(limits) and share > sum(limits):
            raise ValueError(f"{what} needs about {gib(share)} of device memory for its training state; the "
                             f"{len(limits)} {jax.default_backend()} device(s) have {gib(sum(limits))}: use fewer "
                             f"seeds or a smaller replay buffer (--set run.buffer_size=N)")


def abstract_keys(num_seeds: int):
    """The shape of ``seed_keys(seed, num_seeds)``, without making them."""
    import jax

    key = jax.eval_shape(jax.random.PRNGKey, 0)
    return jax.ShapeDtypeStruct((num_seeds, *key.shape), key.dtype)
