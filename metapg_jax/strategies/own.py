"""A stochastic student explores with its own policy: ``--method=own`` (SAC's exploration, ``--student=sac``).

At every step the action is the student's ``sample_action(actor, s, z)`` (SAC: tanh(mean(s) + std(s) z)),
with ``z`` from the ``noise`` group's kind (``metapg_jax.action_noise``): ``--noise=normal`` (the
default here) is the policy's own white Gaussian sampling, ``--noise=pink`` colors it (Eberhard et al., 2023,
section 4: the colored sequence replaces the reparameterisation noise; ``noise.stddev`` is unused, the
policy's std scales it). Only kinds whose ``z`` is standard normal at every step can be a policy's sampling
noise (``NoiseKind.policy_noise``); the others, and adaptive parameter noise, are refused before compile. The
cycle is the loop's (``Trainer.acting_cycle``): ``rollout_steps`` steps, stored, then ``train_steps`` updates,
uniformly random actions during ``run.warmup_steps``.

The name says what runs: the student's own exploration, as Brax, SB3 and CleanRL run SAC. A deterministic
student has no policy noise to sample with: it explores with ``--method=ddpg`` (its actor plus noise).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax

from metapg_jax import action_noise, strategy
from metapg_jax.loop import Trainer


@dataclasses.dataclass(frozen=True)
class OwnPolicyExplorer(strategy.ActingExplorer):
    """The student's stochastic policy with the noise kind's ``z`` as its sampling noise (module docstring); an
    ``ActingExplorer`` whose carry is the kind's process state (a colored sequence, ...)."""

    config: Any

    def init(self, trainer: Trainer, student, key: jax.Array) -> Any:
        return action_noise.init(self.config, trainer.student.action_size)

    def episode_start(self, trainer: Trainer, carry: Any, student, key: jax.Array) -> Any:
        return action_noise.episode_start(self.config, carry, key)

    def act(self, trainer: Trainer, carry: Any, student, normalizer, obs, key: jax.Array):
        learner = trainer.student
        z, _, carry = action_noise.sample(self.config, carry, key)
        return learner.sample_action(student.actor, learner.normalize(normalizer, obs), z), carry

    def metrics(self, carry: Any) -> dict:
        return action_noise.metrics(self.config, carry)


def _schedule(config):
    """Chosen: the policy's own white sampling noise unless ``--noise`` or ``--set noise.kind`` says otherwise
    (the ``noise`` group's default, adaptive parameter noise, is not a sampling noise)."""
    return config.replace(noise=dataclasses.replace(config.noise, kind="normal"))


def _validate(config) -> None:
    run = config.run
    if run.method != NAME:
        return
    if not strategy.student(config.student).stochastic:
        raise ValueError(f"--method={NAME} samples the student's own stochastic policy, and --student="
                         f"{config.student} is deterministic: explore with --method=ddpg --noise=... instead")
    known = action_noise.kinds()
    usable = [name for name, k in known.items() if k.policy_noise]
    if config.noise.kind not in usable:
        what = "is not a policy's sampling noise (a standard normal at every step, scaled by the policy)" \
            if config.noise.kind in known or config.noise.kind == action_noise.PARAMETER_NOISE else "is unknown"
        raise ValueError(f"--noise={config.noise.kind} {what}; with --method={NAME}: {', '.join(sorted(usable))}")
    action_noise.validate(config)
    action_noise.check_warmup(config)

NAME = "own"
strategy.register_explorer(
    NAME, OwnPolicyExplorer, uses_group="noise", schedule=_schedule, validate=_validate, flag=("noise", "kind"),
    label=lambda config: config.noise.kind,
    summary="a stochastic student's own policy (SAC), its sampling noise white or colored (--noise)")
