"""metapg-jax: Learning to Explore with Meta-Policy Gradient (Xu et al., ICML 2018) in JAX."""

from metapg_jax.policy import load_policy

__all__ = ["load_policy"]
