"""Uniformly random actions: ``--method=random``, a control for any student.

Every action of training is drawn uniformly from [-1, 1]^d, whatever the student's policy; the student learns
from those transitions on the loop's acting cycle (``Trainer.acting_cycle``: ``rollout_steps`` steps, stored,
then ``train_steps`` updates) and is evaluated as any other, with its own deterministic policy. It measures how
much any directed exploration matters on a task: a strategy that does not beat it there explores no better
than chance (the exploration benchmark's hard tasks, issue #62's control). Unlike ``run.warmup_steps``, which
also draws uniform actions but makes no updates, the student trains throughout.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax

from metapg_jax import strategy
from metapg_jax.loop import Trainer


@dataclasses.dataclass(frozen=True)
class RandomActionsExplorer(strategy.ActingExplorer):
    """An ``ActingExplorer`` whose action is ``trainer.random_action(key)``; it carries nothing."""

    config: Any

    def init(self, trainer: Trainer, student, key: jax.Array) -> tuple:
        return ()

    def act(self, trainer: Trainer, carry: tuple, student, normalizer, obs, key: jax.Array):
        return trainer.random_action(key), carry


NAME = "random"
strategy.register_explorer(
    NAME, RandomActionsExplorer,
    summary="uniformly random actions in [-1, 1]^d at every step while the student trains (a control)")
