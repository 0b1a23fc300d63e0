"""metapg-jax: Learning to Explore with Meta-Policy Gradient (Xu et al., ICML 2018) in JAX."""

import os as _os


def _default_to_deterministic_gpu_ops() -> None:
    """Add --xla_gpu_deterministic_ops=true to XLA_FLAGS unless XLA_FLAGS already sets that flag.

    A resumed run must equal the uninterrupted one bit for bit (docs/long-runs.md). On a GPU, XLA's
    default flags let two processes round the same program differently (measured on an H200: a run
    killed and resumed in a new process differed from the uninterrupted run from its first metrics
    row on; with this flag the two were equal; results/benchmarks/gpu/README.md). XLA reads XLA_FLAGS
    when the first computation runs, so this must happen before that: importing metapg_jax first
    suffices. CPU-only jaxlib accepts and ignores the flag. It costs speed on a GPU (H200: Meta at 64
    seeds on the JAX task trained at 0.78x, MJX stepping of a MuJoCo task at 512 envs ran at 0.93x;
    results/benchmarks/gpu/README.md, fourth check). Opt out with XLA_FLAGS=--xla_gpu_deterministic_ops=false
    where bit-for-bit resume does not matter.
    """
    flags = _os.environ.get("XLA_FLAGS", "")
    if "xla_gpu_deterministic_ops" not in flags:
        _os.environ["XLA_FLAGS"] = f"{flags} --xla_gpu_deterministic_ops=true".strip()


_default_to_deterministic_gpu_ops()

__all__ = ["load_policy"]


def __getattr__(name: str):
    """``metapg_jax.load_policy`` (``metapg_jax.host.policy``), imported on first use: the package itself
    stays free of the host side (``metapg_jax.host``), which reads files."""
    if name == "load_policy":
        from metapg_jax.host.policy import load_policy

        return load_policy
    raise AttributeError(f"module 'metapg_jax' has no attribute {name!r}")
