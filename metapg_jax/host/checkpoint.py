"""Checkpoints of the whole (seed-batched) ``TrainState`` with orbax, plus run metadata.

A checkpoint is the complete state: student and teacher parameters, all
optimizer states, the replay buffers, the environment states, the normaliser,
PRNG keys and counters, so a resumed run continues bit for bit. Each
checkpoint also stores JSON metadata: the config that built the state, the
number of seeds, the base seed and how many chunks were done.

orbax writes each checkpoint to a temporary folder and renames it when
complete, so a checkpoint that exists is whole; if the latest one is unreadable
anyway (a truncated or corrupted file), ``restore`` warns and falls back to the
previous one. The last ``keep`` [2] checkpoints are kept.

The state is stored as a flat ``{leaf index: array}`` dict (with the leaves'
key paths in the metadata) rather than as the pytree itself: MJX states hold
zero-size arrays that orbax refuses to save, and those are rebuilt from the
expected shapes on restore.
"""

from __future__ import annotations

import os
import warnings
from typing import Any

import jax
import numpy as np
import orbax.checkpoint as ocp


def saved_steps(directory: str) -> list[int]:
    """Chunk counts of the checkpoint folders under ``directory`` (orbax names them by step), sorted;
    [] when there is none or no such folder. Creates nothing (``Checkpointer`` creates the folder)."""
    if not os.path.isdir(directory):
        return []
    return sorted(int(name) for name in os.listdir(directory) if name.isdigit())


class Checkpointer:
    def __init__(self, directory: str, keep: int = 2):
        self.directory = os.path.abspath(directory)
        self.manager = ocp.CheckpointManager(
            self.directory,
            options=ocp.CheckpointManagerOptions(max_to_keep=keep, enable_async_checkpointing=False,
                                                 create=True))

    def steps(self) -> list[int]:
        """Completed checkpoints, by number of chunks done, newest last."""
        self.manager.reload()
        return sorted(self.manager.all_steps())

    def save(self, chunks_done: int, state: Any, meta: dict) -> None:
        """Saves the state after ``chunks_done`` chunks (blocking; atomic by orbax's rename)."""
        flat, paths = _flatten(state)
        self.manager.save(chunks_done, args=ocp.args.Composite(
            state=ocp.args.StandardSave(flat),
            meta=ocp.args.JsonSave({**meta, "chunks_done": chunks_done, "leaf_paths": paths})),
            force=True)
        self.manager.wait_until_finished()

    def restore(self, abstract_state: Any, step: int | None = None) -> tuple[Any, dict]:
        """The newest readable checkpoint (or ``step``): (state, metadata).

        ``abstract_state`` gives the shapes, dtypes and pytree structure
        (``jax.eval_shape`` of the init), or is a function of the checkpoint's
        metadata returning them (a run extended to a larger budget restores
        checkpoints written with the smaller replay capacity). Unreadable
        checkpoints are skipped with a warning; if none can be read, raises
        ``FileNotFoundError``.
        """
        candidates = [step] if step is not None else list(reversed(self.steps()))
        if not candidates:
            raise FileNotFoundError(f"no checkpoint in {self.directory}")
        errors = []
        for s in candidates:
            try:
                # The metadata first (it can decide the shapes), then the state alone.
                meta = dict(self.manager.restore(s, args=ocp.args.Composite(meta=ocp.args.JsonRestore())).meta)
                abstract = abstract_state(meta) if callable(abstract_state) else abstract_state
                abstract = jax.tree.map(ocp.utils.to_shape_dtype_struct, abstract)
                flat_abstract, paths = _flatten(abstract)
                if meta.pop("leaf_paths", None) != paths:
                    raise ValueError("the checkpoint holds a state of another structure")
                out = self.manager.restore(s, args=ocp.args.Composite(state=ocp.args.StandardRestore(flat_abstract)))
                state = _unflatten(abstract, out.state)
                if errors:
                    warnings.warn(f"checkpoint(s) {', '.join(e[0] for e in errors)} in {self.directory} could not be "
                                  f"read ({errors[0][1]}); resumed from the one after {s} chunks instead",
                                  RuntimeWarning, stacklevel=2)
                return state, meta
            except Exception as err:  # noqa: BLE001 - any failure to read means: try the previous one
                errors.append((str(s), f"{type(err).__name__}: {str(err)[:200]}"))
        raise FileNotFoundError(f"no readable checkpoint in {self.directory}: " +
                                "; ".join(f"{s}: {e}" for s, e in errors))

    def close(self) -> None:
        self.manager.close()


def _flatten(tree) -> tuple[dict, list[str]]:
    """{zero-padded leaf index: leaf} without zero-size leaves, and every leaf's key path."""
    leaves = jax.tree_util.tree_flatten_with_path(tree)[0]
    flat = {f"{i:05d}": x for i, (_, x) in enumerate(leaves) if int(np.prod(np.shape(x))) > 0}
    return flat, [jax.tree_util.keystr(path) for path, _ in leaves]


def _unflatten(abstract, flat: dict):
    leaves, treedef = jax.tree_util.tree_flatten(abstract)
    out = []
    for i, a in enumerate(leaves):
        if int(np.prod(a.shape)) == 0:
            out.append(jax.numpy.zeros(a.shape, a.dtype))
            continue
        x = flat[f"{i:05d}"]
        if tuple(np.shape(x)) != tuple(a.shape):
            raise ValueError(f"checkpoint array of shape {np.shape(x)} where {a.shape} was expected")
        out.append(x)
    return jax.tree_util.tree_unflatten(treedef, out)
