"""The host side of metapg-jax: everything that touches files, processes or the terminal.

The rest of ``metapg_jax`` (what a notebook imports to build and ``jit`` a training program) never
imports this package (``tests/test_imports.py``):

* ``files``: atomic JSON, JSON lines, NumPy archives;
* ``metrics``: a chunk's metrics as rows, training time, learning curves and their plot;
* ``progress``: the progress bar and peak memory;
* ``tensorboard``: TensorBoard event files;
* ``provenance``: commit, uncommitted changes, machine;
* ``compile_cache``: the persistent XLA compilation cache;
* ``checkpoint``: orbax checkpoints of the seed-batched training state;
* ``policy``: exported policies (``policy.npz``), written and loaded with NumPy alone;
* ``runner``: the chunk loop the commands share, with its signals and stop line.
"""
