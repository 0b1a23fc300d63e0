"""The uniform teacher (``--teacher=uniform``, a control): D0 is uniformly random actions, and nothing is learned.

Algorithm 1's cycle runs unchanged around it (the look-ahead on D0, D1 from pi', the meta reward, the student's
updates), so a uniform teacher's run differs from a learned teacher's in D0's actions only. If a learned teacher
does no better than this, what it contributes is a share of random data in the buffer, not what it learned
(results/learned/README.md, the controls). No parameters; ``meta.lr`` and ``meta.teacher_steps`` do not apply.
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp

from metapg_jax import teacher


@dataclasses.dataclass(frozen=True)
class UniformTeacher(teacher.Teacher):
    """``teacher.Teacher`` with no parameters: a ~ U[-1, 1]^A whatever the state."""

    def init(self, key: jax.Array) -> teacher.TeacherState:
        return self.new_state({}, ())

    def sample(self, params, student_actor, obs_normalized, key):
        action = jax.random.uniform(key, (*obs_normalized.shape[:-1], self.action_size), jnp.float32, -1.0, 1.0)
        return action, action

    def update(self, state, student_actor, obs_normalized, raw_actions, meta_reward):
        return state

    def diagnostics(self, params, student_actor, obs_normalized) -> dict:
        """U[-1, 1]'s log-std (log 1/sqrt(3)), its entropy (log 2 per action dimension) and its mean's (0)
        RMS distance from the student's action."""
        student = self.student.actor_apply(student_actor, obs_normalized)
        return {"teacher_log_std": jnp.asarray(-0.5 * math.log(3.0), jnp.float32),
                "teacher_entropy": jnp.asarray(self.action_size * math.log(2.0), jnp.float32),
                "teacher_mean_distance": jnp.sqrt(jnp.mean(jnp.square(student)))}


teacher.register_design("uniform", lambda cfg, student, config: UniformTeacher(cfg, student),
                        "uniformly random actions, nothing learned (a control)")
