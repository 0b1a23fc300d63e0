import os

os.environ.setdefault("JAX_PLATFORMS", "cpu")
# No persistent compile cache unless a test names one (metapg_jax/compile_cache.py): the suite never
# writes to ~/.cache and never starts warm from an earlier session. The subprocesses some tests start
# inherit this. Measured on this 2-core machine: a session-wide shared cache did not make the suite
# faster (its tiny programs mostly differ in shapes; test_cli + test_train used 482 s of CPU with it,
# 377 s without, within this shared machine's noise).
os.environ.setdefault("JAX_ENABLE_COMPILATION_CACHE", "false")
