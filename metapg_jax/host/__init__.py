"""The host side of metapg-jax: everything that touches files, processes or the terminal.

The rest of ``metapg_jax`` (what a notebook imports to build and ``jit`` a training program) never
imports this package (``tests/test_imports.py``):

* ``runfiles``: atomic JSON, JSON lines, NumPy archives;
* ``metric_rows``: a chunk's metrics as rows, training time, learning curves and their plot;
* ``terminal``: the progress bar and peak memory;
* ``tb_events``: TensorBoard event files and their logger (a cycle row's metrics are tagged ``<explorer>/<name>``,
  e.g. ``meta/meta_reward``; runs written before that tagged them ``teacher/`` and resume as they are);
* ``provenance``: commit, uncommitted changes, machine;
* ``compile_cache``: the persistent XLA compilation cache;
* ``checkpoint``: orbax checkpoints of the seed-batched training state;
* ``policy``: exported policies (``policy.npz``), written and loaded with NumPy alone;
* ``runner``: the chunk loop the commands share, with its signals and stop line;
* ``driver``: the training driver (a config, its run args and a folder in; a trained run folder out), used by
  ``experiments.run``, the grid engine and notebooks, and its ``Recorder`` (a chunk's rows to the files and the
  loggers), which ``experiments.sweep`` shares;
* ``loggers``: the ``Logger`` interface the driver reports to, several as one, plain functions, the progress bar;
* ``wandb_runs``: Weights & Biases, one W&B run per seed (``--wandb``; wandb is imported here only).
"""
