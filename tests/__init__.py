"""The test suite. Its programs are compiled by XLA at optimisation level 0 (set here, before JAX is
imported, so that pytest's workers, the subprocesses the tests start and ``python -m tests.golden`` all
compile the same way): the suite's programs are tiny and run for seconds at most, so the compile is most of
their cost, and level 0 compiles them about 10-30% faster than level 1 (and level 1 1.4x faster than the default
level 2) while running slower (results/measurements/test-suite.md, "Optimisation levels"). The two tests that
train for long (tests/test_train.py ``_learning_run``) ask for level 1 for their programs (``RUN_FAST``). The
numbers differ from other levels' in float32 round-off, so tests/golden_numbers.json holds the numbers at
level 0; an XLA_FLAGS that already names the level is left as it is."""

import os

LEVEL_FLAG = "--xla_backend_optimization_level=0"
# jax.jit(..., compiler_options=RUN_FAST): a program that runs long enough for XLA's optimisations to pay off.
RUN_FAST = {"xla_backend_optimization_level": 1}


def _xla_optimisation_level() -> None:
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_backend_optimization_level" not in flags:
        os.environ["XLA_FLAGS"] = f"{flags} {LEVEL_FLAG}".strip()


def xla_flags(*extra: str) -> str:
    """XLA_FLAGS for a subprocess that sets flags of its own: the suite's optimisation level and ``extra``."""
    level = [f for f in os.environ.get("XLA_FLAGS", "").split() if "xla_backend_optimization_level" in f]
    return " ".join(level + list(extra))


_xla_optimisation_level()
