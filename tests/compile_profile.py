"""A pytest plugin that records, per test, where its time went: JAX tracing, lowering and XLA compiling (the
seconds JAX reports through ``jax.monitoring``), programs loaded from the persistent compile cache, and the
programs that took over a second to compile (the tests' own process only, not the subprocesses some
tests start), and the CPU seconds (user + system) of the test's process (``cpu``, all its threads) and of the
subprocesses it started and waited for (``children_cpu``).

    python -m pytest -q -n 2 -p tests.compile_profile

writes one JSON line per test to ``$METAPG_COMPILE_PROFILE/<worker>.jsonl`` (default: the folder
``compile-profile`` in the working directory). ``results/measurements/test-suite.md`` has what it found.
"""

import json
import os
import resource
import time

import pytest

_RECORD: dict = {}


def _reset() -> None:
    _RECORD.update(trace=0.0, lower=0.0, compile=0.0, loaded=0, compiled=[])


def _duration(event: str, seconds: float, **kwargs) -> None:
    if event.endswith("/jaxpr_trace_duration"):
        _RECORD["trace"] += seconds
    elif event.endswith("/jaxpr_to_mlir_module_duration"):
        _RECORD["lower"] += seconds
    elif event.endswith("/backend_compile_duration"):  # a compile, or a load from the persistent cache
        _RECORD["compile"] += seconds
        if seconds > 1.0:
            _RECORD["compiled"].append([kwargs.get("fun_name"), round(seconds, 1)])


def _event(event: str, **kwargs) -> None:
    if event == "/jax/compilation_cache/cache_hits":
        _RECORD["loaded"] += 1


def pytest_configure(config):
    from jax import monitoring

    monitoring.register_event_duration_secs_listener(_duration)
    monitoring.register_event_listener(_event)
    _reset()


def _cpu() -> tuple[float, float]:
    """(this process's CPU seconds, its waited-for children's), user + system."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime, children.ru_utime + children.ru_stime


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    _reset()
    start, (own, children) = time.perf_counter(), _cpu()
    yield
    own_end, children_end = _cpu()
    _RECORD.update(cpu=own_end - own, children_cpu=children_end - children)
    folder = os.environ.get("METAPG_COMPILE_PROFILE", "compile-profile")
    os.makedirs(folder, exist_ok=True)
    row = {"test": item.nodeid, "seconds": round(time.perf_counter() - start, 3),
           **{k: round(v, 3) if isinstance(v, float) else v for k, v in _RECORD.items()}}
    with open(os.path.join(folder, f"{os.environ.get('PYTEST_XDIST_WORKER', 'main')}.jsonl"), "a") as f:
        f.write(json.dumps(row) + "\n")
