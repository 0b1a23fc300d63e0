"""The persistent XLA compilation cache: compiled training programs kept on disk between runs.

A resumed run, the next call of a ``reproduce`` grid and a rerun of the same config load the
compiled program instead of compiling it again (an extension too when its replay capacity does
not change: budgets of 1M steps and more, or a set ``run.buffer_size``; below that the capacity
grows with the budget, the shapes change and the program compiles afresh). Measured on the
2-core CPU machine with another run beside it (docs/long-runs.md, which names the tasks): a
MuJoCo task's training program on MJX (Meta, 2 seeds) compiled in 469 s cold and in 97 s from
the cache (what is left is tracing and lowering, which the cache does not skip); the JAX task's
in 33 s and 4.9 s. The numbers the run produces are the same bit for bit (``tests/test_longrun.py``).

JAX's own cache does the work; this module picks the folder, turns it on and counts what it did:

* ``experiments.run --compile-cache DIR`` (or ``off``), else ``JAX_COMPILATION_CACHE_DIR``, else
  :data:`DEFAULT_DIR` (``$XDG_CACHE_HOME/metapg-jax/xla``, by default ``~/.cache/metapg-jax/xla``);
  ``JAX_ENABLE_COMPILATION_CACHE=false`` (JAX's own switch) turns it off unless ``--compile-cache``
  names a folder.
* The key is XLA's: the lowered program, the compile options, the jax/jaxlib versions and the
  machine's CPU features; any change of config, shapes or code compiles afresh.
* Our folders (the default, or one named by ``--compile-cache``) hold at most :data:`MAX_BYTES`
  (least recently used entries go first; reads and writes hold a file lock, so concurrent runs
  may share one). A folder from ``JAX_COMPILATION_CACHE_DIR`` is JAX's general one, perhaps
  shared with other projects: it keeps JAX's own size limit (``JAX_COMPILATION_CACHE_MAX_SIZE``,
  by default none).
* :func:`counts` reports JAX's own events (programs loaded, compiled, stored), so a run states
  what its compile time was; programs that compile in under a second are not stored (JAX's
  ``jax_persistent_cache_min_compile_time_secs``).
* The cache is trusted: whoever can write to the folder can run code in your runs (JAX's
  warning); keep it private. An entry cut short (a process killed while writing it) is not
  replaced: JAX warns and compiles afresh on every later run (the run reports "0 loaded"); delete
  the entry named in the warning, or the folder.
* ``experiments.bench`` and ``experiments.bench_replay`` turn the cache off: their compile times
  are cold compiles.
* A job of several processes on CPU runs without it (:func:`resolve` says no; the run's compile line
  says why). JAX writes entries from process 0 only, and on CPU process 1 did not find them: a resume
  loaded process 0's program from the cache and compiled process 1's afresh, and the two processes
  hung in their first Gloo collective (a tiny two-process job killed and resumed with ``--resume``
  never finished; without the cache it finished). On GPU JAX strips the device assignment from the key
  so that every process finds process 0's entry; the cache stays on there.
"""

from __future__ import annotations

import collections
import os

DEFAULT_DIR = os.path.join(os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"),
                           "metapg-jax", "xla")
MAX_BYTES = 2 * 2**30
_OFF = ("0", "false", "f", "no", "n", "off")
_EVENTS = {"/jax/compilation_cache/compile_requests_use_cache": "requests",
           "/jax/compilation_cache/cache_hits": "loaded",
           "/jax/compilation_cache/cache_misses": "stored"}  # JAX records a "miss" when it writes an entry
_counts: collections.Counter = collections.Counter()
_listening = False


def resolve(flag: str | None) -> str | None:
    """The cache folder to use (created if missing), or None when the cache is off.

    ``flag`` is ``--compile-cache``'s value: a folder, ``off``, or None for the environment's choice.
    Raises ``ValueError`` with one line when the folder cannot be used.
    """
    if flag is not None:
        path = None if flag.strip().lower() == "off" else flag
    elif os.environ.get("JAX_ENABLE_COMPILATION_CACHE", "").strip().lower() in _OFF:
        path = None
    else:
        path = os.environ.get("JAX_COMPILATION_CACHE_DIR") or DEFAULT_DIR
    if path is None or several_cpu_processes():
        return None
    if not path.strip():
        raise ValueError("--compile-cache needs a folder (or 'off')")
    if "://" in path:  # a remote cache (e.g. gs://...): JAX's own file handling (etils) takes it as is
        return path
    path = _local(path)
    if os.path.exists(path) and not os.path.isdir(path):
        raise ValueError(f"compile cache {path} is a file, not a folder; pass --compile-cache DIR or off")
    try:
        os.makedirs(path, exist_ok=True)
    except OSError as err:
        raise ValueError(f"compile cache {path} cannot be created ({err.strerror}); "
                         f"pass --compile-cache DIR or off") from None
    if not os.access(path, os.W_OK):
        raise ValueError(f"compile cache {path} is not writable; pass --compile-cache DIR or off")
    return path


def several_cpu_processes() -> bool:
    """Whether this process is one of several of a JAX distributed job on the CPU backend (the module's
    docstring says why such a job runs without the cache). False, without touching JAX's backends, when
    ``jax.distributed`` was not started."""
    import jax

    return jax.distributed.is_initialized() and jax.process_count() > 1 and jax.default_backend() == "cpu"


def _local(path: str) -> str:
    """A local folder's path as :func:`resolve` returns it (user expanded, absolute)."""
    return os.path.abspath(os.path.expanduser(path))


def enable(path: str | None) -> None:
    """Points this process's next compiles at ``path`` (None: no persistent cache).

    Safe to call again with another folder (``experiments.reproduce`` runs many cells in one
    process, the tests many runs): JAX's cache is reset when the choice changes.
    """
    import jax
    from jax.experimental.compilation_cache import compilation_cache

    max_size = _max_size(path)
    if path == current() and (path is None or jax.config.jax_compilation_cache_max_size == max_size):
        return
    jax.config.update("jax_enable_compilation_cache", path is not None)
    if path is not None:
        jax.config.update("jax_compilation_cache_dir", path)
        jax.config.update("jax_compilation_cache_max_size", max_size)
    compilation_cache.reset_cache()


def _max_size(path: str | None) -> int:
    """MAX_BYTES for our folders; JAX's own limit (-1: none) for the folder JAX_COMPILATION_CACHE_DIR names."""
    env = os.environ.get("JAX_COMPILATION_CACHE_DIR")
    if path is not None and env and path in (env, _local(env)):
        try:
            return int(os.environ.get("JAX_COMPILATION_CACHE_MAX_SIZE", "-1"))
        except ValueError:
            return -1
    return MAX_BYTES


def counts() -> dict[str, int]:
    """Running totals of this process's persistent-cache events: ``requests`` (compiles that asked the
    cache), ``loaded`` (found there), ``stored`` (written there); the difference of two calls is what
    happened in between. Compiles that did not ask (cache off) are not counted."""
    global _listening
    if not _listening:
        import jax.monitoring

        def listen(event: str, **kwargs) -> None:
            if event in _EVENTS:
                _counts[_EVENTS[event]] += 1

        jax.monitoring.register_event_listener(listen)
        _listening = True
    return {k: _counts[k] for k in ("requests", "loaded", "stored")}


def describe(path: str | None, before: dict[str, int], after: dict[str, int]) -> tuple[str, dict]:
    """A run's one-line account of its compile (e.g. "compile cache /x: 2 programs loaded, 0 compiled,
    0 stored") and the numbers for its summary.json."""
    if path is None:
        why = ": several processes on CPU, see metapg_jax/host/compile_cache.py" if several_cpu_processes() else ""
        return f"compile cache off{why}", {"compile_cache": None}
    d = {k: after[k] - before[k] for k in after}
    n = {"loaded": d["loaded"], "compiled": d["requests"] - d["loaded"], "stored": d["stored"]}
    return (f"compile cache {path}: {n['loaded']} program(s) loaded, {n['compiled']} compiled, "
            f"{n['stored']} stored"), {"compile_cache": path, **{f"compile_cache_{k}": v for k, v in n.items()}}


def current() -> str | None:
    """The folder this process's compiles use now, or None."""
    import jax

    return jax.config.jax_compilation_cache_dir if jax.config.jax_enable_compilation_cache else None

