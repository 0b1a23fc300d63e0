"""Several settings of a config in one program: a run's seed axis widened to (settings x seeds).

A *setting* gives values to some config fields, e.g. ``{"meta.lr": 1e-3, "meta.init_log_std": -1.0}``.
Fields that enter the computation only as numbers (learning rates, tau, gamma, noise scales, the
teacher's initial log-std, ...) can differ along the batch: ``Sweep.init(key, values)`` and
``Sweep.train_chunk(state, values)`` build the trainer of one element with those fields set to
the element's (traced) values, and a ``vmap_seeds`` over a flat batch of (setting, seed) pairs runs
every setting and seed in one compiled program. Fields that change shapes or the program's
structure (network sizes, schedules, loop counts, a teacher design, anything read by a Python
``if``) cannot; ``structural_fields`` finds them by tracing the program with each field as a
traced value, and ``experiments.sweep`` runs one program per combination of their values.

Each element computes what a run of its setting computes; the numbers equal separate runs of the
settings up to float32 round-off (XLA compiles the larger batch differently; ``tests/test_sweep.py``).
"""

from __future__ import annotations

import dataclasses
from typing import Any, Sequence

import jax
import jax.numpy as jnp
from brax.envs.base import Env

from metapg_jax import strategy
from metapg_jax.config import Config
from metapg_jax.loop import TrainState, Trainer

# What tracing a field as a value raises when the program needs it as a Python value.
_STRUCTURAL_ERRORS = (jax.errors.ConcretizationTypeError, jax.errors.TracerBoolConversionError,
                      jax.errors.TracerIntegerConversionError, jax.errors.TracerArrayConversionError,
                      TypeError, ValueError, IndexError)


def get_field(config: Config, dotted: str) -> Any:
    obj = config
    for part in dotted.split("."):
        obj = getattr(obj, part)
    return obj


def set_fields(config: Config, values: dict[str, Any]) -> Config:
    """``config`` with dotted fields replaced by ``values`` as given (traced arrays allowed; no
    validation or type coercion: validate the concrete settings with ``config.override`` first)."""
    for dotted, value in values.items():
        parts = dotted.split(".")
        if len(parts) == 1:
            config = config.replace(**{parts[0]: value})
        else:
            group = getattr(config, parts[0])
            config = config.replace(**{parts[0]: dataclasses.replace(group, **{parts[1]: value})})
    return config


def is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


@dataclasses.dataclass(frozen=True)
class Sweep:
    """The trainer of ``config`` with ``fields`` taken from a per-element vector of values."""

    config: Config
    env: Env
    fields: tuple[str, ...]

    def trainer(self, values: jax.Array) -> Trainer:
        """The trainer of one element: ``values[i]`` is the value of ``fields[i]`` (as float32)."""
        types = [type(get_field(self.config, f)) for f in self.fields]
        cfg = set_fields(self.config, {f: (values[i] if t is float else values[i].astype(jnp.int32))
                                       for i, (f, t) in enumerate(zip(self.fields, types))})
        obs_size, action_size = int(self.env.observation_size), int(self.env.action_size)
        return Trainer(cfg, self.env, strategy.student(cfg.student).make(cfg, obs_size, action_size),
                       strategy.explorer(cfg.run.method).make(cfg))

    def init(self, key: jax.Array, values: jax.Array) -> TrainState:
        return self.trainer(values).init(key)

    def train_chunk(self, state: TrainState, values: jax.Array) -> tuple[TrainState, dict]:
        return self.trainer(values).train_chunk(state)

    def train(self, key: jax.Array, values: jax.Array) -> tuple[TrainState, dict]:
        """The whole run of one element as one program (``Trainer.train``)."""
        return self.trainer(values).train(key)

    def values(self, settings: Sequence[Config]) -> jax.Array:
        """(settings, fields) float32: the swept fields' values of each setting's concrete config."""
        return jnp.asarray([[float(get_field(c, f)) for f in self.fields] for c in settings], jnp.float32)


# (config, field) -> whether the field is structural: a field's answer depends on the config alone (``env`` is
# the config's task), and a sweep started again in the same process (a resume, a notebook) need not trace again.
_STRUCTURAL: dict[tuple[Config, str], bool] = {}


def structural_fields(config: Config, env: Env, fields: Sequence[str]) -> list[str]:
    """The fields among ``fields`` that cannot vary within one program: not a number in ``config``, or
    a number the program reads as a Python value (found by tracing init and a chunk with that field
    alone as a traced value; no compile). ``env`` is ``config``'s task; each answer is kept for the
    process."""
    key = jax.random.PRNGKey(0)
    for field in fields:
        if (config, field) in _STRUCTURAL:
            continue
        structural = not is_number(get_field(config, field))
        if not structural:
            sweep = Sweep(config, env, (field,))
            value = sweep.values([config])[0]
            try:
                jax.eval_shape(lambda k, v: sweep.train_chunk(sweep.init(k, v), v), key, value)
            except _STRUCTURAL_ERRORS:
                structural = True
        _STRUCTURAL[(config, field)] = structural
    return [field for field in fields if _STRUCTURAL[(config, field)]]
