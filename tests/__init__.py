"""The test suite. Its programs are compiled by XLA at optimisation level 1 (set here, before JAX is
imported, so that pytest's workers, the subprocesses the tests start and ``python -m tests.golden`` all
compile the same way): a tiny training program compiles about 1.4x faster than at the default level 2
and runs as fast (measured on the 2-core CPU: 17.8 s vs 25.9 s for a test that compiles three programs).
The numbers differ from level 2's in float32 round-off, so tests/golden_numbers.json holds the numbers at
level 1; an XLA_FLAGS that already names the level is left as it is."""

import os


def _xla_optimisation_level() -> None:
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_backend_optimization_level" not in flags:
        os.environ["XLA_FLAGS"] = f"{flags} --xla_backend_optimization_level=1".strip()


_xla_optimisation_level()
