"""The residual teacher (``--teacher=residual``, ours): the student's action plus a learned, bounded offset, with a
learned state-dependent scale.

    pi_e(a|s) = N(mu_student(s) + max_offset * tanh(g(s)), diag sigma(s)^2)

``g`` is an MLP whose last layer starts at zero, so the teacher starts as the student with Gaussian noise of scale
exp(``meta.init_log_std``) and moves away from it only as far as REINFORCE on the meta reward takes it, at most
``residual.max_offset`` per action dimension. ``sigma(s)`` is the log-std MLP of the paper's designs. The student's
action enters under ``stop_gradient`` (the teacher never changes the student), as in the variance design.

Why (results/learned/README.md, hypothesis H1): the paper's independent teacher starts as a network of its own and
barely moves, so its D0 is data about a policy 0.8-1.0 (RMS) away from the student's, which an off-policy learner
extrapolates from badly (Fujimoto et al., 2019). A residual teacher's D0 is always about a policy the student can
use. The offset is kept near the student by a bound rather than a KL or distance penalty: the REINFORCE loss scales
with the meta reward, whose size changes by orders of magnitude between tasks and over training, so a penalty's
weight would have to be tuned per task; a bound needs none.
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp

from metapg_jax import strategy, teacher
from metapg_jax.networks import MLP


@dataclasses.dataclass(frozen=True)
class ResidualConfig:
    """The residual teacher's bound (the ``residual`` group)."""

    max_offset: float = 0.3  # per action dimension, of the action range [-1, 1] (ours)


@dataclasses.dataclass(frozen=True)
class ResidualTeacher(teacher.Teacher):
    """``teacher.Teacher`` with parameters {'offset': MLP with a zero last layer, 'log_std': MLP}."""

    max_offset: float = 0.3

    def _offset_net(self) -> MLP:
        return MLP(self.action_size, tuple(self.cfg.hidden), self.cfg.layer_norm, final_init=0.0)

    def init(self, key: jax.Array) -> teacher.TeacherState:
        k_offset, k_std = jax.random.split(key)
        obs = jnp.zeros((self.student.obs_size,), jnp.float32)
        params = {"offset": self._offset_net().init(k_offset, obs), "log_std": self._log_std_net().init(k_std, obs)}
        return self.new_state(params, self.optimizer.init(params))

    def offset(self, params, obs_normalized: jax.Array) -> jax.Array:
        """max_offset * tanh(g(s)): 0 at initialisation, within +-max_offset always."""
        return self.max_offset * jnp.tanh(self._offset_net().apply(params["offset"], obs_normalized))

    def distribution(self, params, student_actor, obs_normalized):
        mean = jax.lax.stop_gradient(self.student.actor_apply(student_actor, obs_normalized))
        log_std = self.squash_log_std(self._log_std_net().apply(params["log_std"], obs_normalized))
        return mean + self.offset(params, obs_normalized), log_std


def _validate(config) -> None:
    b = config.residual.max_offset
    if not (math.isfinite(b) and b > 0):
        raise ValueError(f"residual.max_offset must be a finite number > 0, got {b!r}")
    if config.meta.teacher == NAME and not config.meta.state_dependent_std:
        raise ValueError("the residual teacher's log-std is a network: meta.state_dependent_std=false does not "
                         "apply to it")


NAME = "residual"
strategy.register_group(NAME, ResidualConfig, validate=_validate)
teacher.register_design(NAME, lambda cfg, student, config: ResidualTeacher(cfg, student, config.residual.max_offset),
                        "the student's action plus a learned offset (at most residual.max_offset) and scale")
