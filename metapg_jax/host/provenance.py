"""What a run records about where it came from: the commit, whether the tree had uncommitted changes (and
the changes themselves), and the machine."""

from __future__ import annotations

import os


def _git(*args: str) -> str:
    """A git command's output in the project's checkout ('' when git fails or is missing)."""
    import subprocess

    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    try:
        return subprocess.run(["git", *args], cwd=root, capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


# Tracked files outside ``results/``: the code a run's provenance speaks for (``results/`` holds outputs).
_CODE = ("--", ".", ":(exclude)results")


def cpu_fingerprint() -> str:
    """A short hash of the CPU's model name and instruction-set flags (``/proc/cpuinfo``; '' elsewhere). XLA
    compiles for the CPU it runs on, so float32 results are equal bit for bit only between machines with the
    same fingerprint (and JAX version); elsewhere a chaotic task's runs differ after round-off grows."""
    import hashlib

    model = ""
    if os.path.exists("/proc/cpuinfo"):
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith(("model name", "flags")):
                    model += line.split(":", 1)[1].strip() + "\n"
                if line.startswith("flags"):
                    break
    return hashlib.sha256(model.encode()).hexdigest()[:16] if model else ""


# The installed distributions whose versions can change a run's numbers (XLA's compiler, MuJoCo's C engine,
# the numerics libraries) or its meaning (the environments' definitions).
# (``mujoco`` 4 is a metapackage; its compiled engine is ``mujoco-core``.) Versions, not builds: a reinstall of the
# same versions is not told apart.
PACKAGES = ("jax", "jaxlib", "mujoco", "mujoco-core", "mujoco-mjx", "brax", "flax", "optax", "chex", "numpy",
            "gymnasium", "orbax-checkpoint")


def package_versions(names: tuple[str, ...] = PACKAGES) -> dict[str, str | None]:
    """{distribution: installed version, None where it is not installed} for ``names``."""
    from importlib import metadata

    out = {}
    for name in names:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def record() -> dict:
    """The commit (and whether the tree had changes) and the machine (CPU fingerprint, Python, the versions of
    ``PACKAGES``), recorded with every run: float32 results are equal bit for bit only on the same CPU with the
    same package builds.

    ``dirty``: tracked files outside ``results/`` differ from the commit. ``results/`` holds outputs (reports
    that a grid or screen rewrites between its cells), not code, so a rewritten report does not mark the
    cells that start after it. ``uncommitted_diff`` gives the changes themselves."""
    import platform

    machine = {"platform": platform.platform(), "processor": platform.machine(), "cpu": cpu_fingerprint(),
               "cpu_count": os.cpu_count(), "python": platform.python_version(), "packages": package_versions()}
    try:
        import jax

        machine.update(jax_version=jax.__version__, jax_backend=jax.default_backend(),
                       jax_devices=[str(d) for d in jax.devices()])
    except Exception as err:  # noqa: BLE001 - provenance must never stop a run
        machine["jax_error"] = repr(err)
    return {"commit": _git("rev-parse", "HEAD") or "unknown",
            "dirty": bool(_git("status", "--porcelain", "--untracked-files=no", *_CODE)),
            "machine": machine}


def uncommitted_diff() -> str:
    """The uncommitted changes that make ``record()`` dirty: ``git diff HEAD`` of the tracked files outside
    ``results/`` ('' for a clean tree)."""
    return _git("diff", "HEAD", "--no-color", *_CODE)
