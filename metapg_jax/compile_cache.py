"""The persistent XLA compilation cache: compiled training programs kept on disk between runs.

A resumed or extended run, the next call of a ``reproduce`` grid and a rerun of the same config
load the compiled program instead of compiling it again. Measured on the 2-core CPU machine with
another run beside it: Hopper's training program (Meta, 2 seeds) compiled in 469 s cold and in
97 s from the cache (what is left is tracing and lowering, which the cache does not skip); the
JAX Pendulum's in 33 s and 4.9 s. The numbers the run produces are the same bit for bit
(``tests/test_longrun.py``).

JAX's own cache does the work; this module only picks the folder and turns it on:

* ``experiments.run --compile-cache DIR`` (or ``off``), else ``JAX_COMPILATION_CACHE_DIR``, else
  :data:`DEFAULT_DIR` (``$XDG_CACHE_HOME/metapg-jax/xla``, by default ``~/.cache/metapg-jax/xla``);
  ``JAX_ENABLE_COMPILATION_CACHE=false`` (JAX's own switch) turns it off unless ``--compile-cache``
  names a folder.
* The key is XLA's: the lowered program, the compile options, the jax/jaxlib versions and the
  machine's CPU features; any change of config, shapes or code compiles afresh.
* The folder is capped at :data:`MAX_BYTES` (least recently used entries go first; reads and
  writes hold a file lock, so concurrent runs may share it).
* The cache is trusted: whoever can write to the folder can run code in your runs (JAX's
  warning); keep it private. An entry cut short (a process killed while writing it) makes JAX
  warn and compile afresh; deleting the folder clears it.
* ``experiments.bench`` turns the cache off: its compile times are always cold compiles.
"""

from __future__ import annotations

import os

DEFAULT_DIR = os.path.join(os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"),
                           "metapg-jax", "xla")
MAX_BYTES = 2 * 2**30
_OFF = ("0", "false", "no", "off")


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
    if path is None:
        return None
    if not path.strip():
        raise ValueError("--compile-cache needs a folder (or 'off')")
    path = os.path.abspath(os.path.expanduser(path))
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


def enable(path: str | None) -> None:
    """Points this process's next compiles at ``path`` (None: no persistent cache).

    Safe to call again with another folder (``experiments.reproduce`` runs many cells in one
    process, the tests many runs): JAX's cache is reset when the choice changes.
    """
    import jax
    from jax.experimental.compilation_cache import compilation_cache

    if path == current() and (path is None or jax.config.jax_compilation_cache_max_size == MAX_BYTES):
        return
    jax.config.update("jax_enable_compilation_cache", path is not None)
    if path is not None:
        jax.config.update("jax_compilation_cache_dir", path)
        jax.config.update("jax_compilation_cache_max_size", MAX_BYTES)
    compilation_cache.reset_cache()


def current() -> str | None:
    """The folder this process's compiles use now, or None."""
    import jax

    return jax.config.jax_compilation_cache_dir if jax.config.jax_enable_compilation_cache else None


def entries(path: str | None) -> int:
    """How many compiled programs the folder holds (0 for None or a missing folder)."""
    if path is None or not os.path.isdir(path):
        return 0
    return sum(name.endswith("-cache") for name in os.listdir(path))
