"""The built-in strategies, one file each: the students ``ddpg`` and ``td3``, the explorers ``ddpg`` (the DDPG
baselines' noise, ``noise.py``) and ``meta`` (Algorithm 1's teacher). Every module here registers itself
with ``metapg_jax.strategy``, which imports them all the first time it is asked (nothing else names them);
a new built-in strategy is a new file here, a user's is a file loaded with ``--plugin``."""
