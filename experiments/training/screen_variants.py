"""The screen's teacher variants (``experiments.screen``): each one's change from the paper preset, as run options,
and the hypothesis behind it, written before it was run; the control and the noise baselines beside them."""

from __future__ import annotations

import dataclasses
from typing import Callable

from experiments.grid.methods import METHODS
from experiments.grid.spec import Method, method

CONTROL = "paper-teacher"
BASELINES = ("ddpg-paramnoise", "ddpg-normal")
DEFAULT_TASKS = ("hopper", "halfcheetah")
DEFAULT_STEPS = 300_000
LOG_STD_FLOOR = -2.3  # sigma >= 0.1 in normalised action units (TD3's exploration noise)


@dataclasses.dataclass(frozen=True)
class Variant:
    label: str
    change: str  # in words
    hypothesis: str
    sets: Callable  # (paper-preset Meta config of the task) -> list of "group.field=value", None = no-op here
    method: Method = method("meta", teacher="independent")


def _ddpg_ratio(cfg) -> list[str] | None:
    """DDPG's updates per stored step (50 per 100) for the student; the look-ahead keeps its updates."""
    train = cfg.steps_per_cycle // 2
    if train == cfg.run.train_steps:
        return None
    return [f"run.train_steps={train}", f"meta.lookahead_steps={cfg.meta.lookahead_steps or cfg.run.train_steps}"]


def _one_step(cfg) -> list[str] | None:
    return None if cfg.meta.teacher_steps == 1 else ["meta.teacher_steps=1"]


def _frozen(cfg) -> list[str]:
    return ["meta.lr=0"]


def _combined(*parts: Callable) -> Callable:
    """The union of the parts' overrides (a part that is the preset already adds nothing)."""
    return lambda cfg: [s for part in parts for s in (part(cfg) or [])]


VARIANTS: dict[str, Variant] = {
    CONTROL: Variant(
        "paper teacher", "the paper preset (control)",
        "Control: Algorithm 1 with the paper preset's schedule.", lambda cfg: []),
    "ddpg-paramnoise": Variant(
        "DDPG (param noise)", "no teacher: adaptive parameter noise 0.2 (the paper's baseline)",
        "Baseline.", lambda cfg: [], METHODS["ddpg-paramnoise"]),
    "ddpg-normal": Variant(
        "DDPG (normal noise)", "no teacher: Gaussian action noise 0.2",
        "Baseline.", lambda cfg: [], METHODS["ddpg-normal"]),
    "one-teacher-step": Variant(
        "1 teacher step per cycle", "`meta.teacher_steps=1` (HalfCheetah's preset: 100)",
        "100 Adam steps on one scalar meta reward per cycle overfit the teacher to that sample's noise and "
        "drive its log-std to the floor, so exploration collapses; one step keeps it exploring (the MJX "
        "ablation at 300k: 1,533 -> 2,810 on HalfCheetah).",
        _one_step),
    "variance-teacher": Variant(
        "variance teacher", "`--teacher=variance`: the teacher's mean is the student's action, only its "
                            "log-std is learned (the paper's design (i); the independent teacher is its design (ii))",
        "The independent teacher starts as a network of its own and barely moves at the paper's learning rate, so "
        "D0 holds actions far from the student's (RMS distance ~0.8-1.0 of the action range on Hopper): data about "
        "a policy the student is not. Exploring around the student's action makes D0 informative for it.",
        lambda cfg: [], method("meta", teacher="variance")),
    "teacher-lr-1e-3": Variant(
        "teacher lr 1e-3", "`meta.lr=1e-3` (paper 1e-4)",
        "At 1e-4 with one REINFORCE step per cycle the teacher's log-std moves from -0.50 to about -0.40 in 300k "
        "steps on Hopper: whatever the meta reward says, the teacher cannot act on it within the budget.",
        lambda cfg: ["meta.lr=0.001"]),
    "frozen-teacher": Variant(
        "frozen teacher", "`meta.lr=0`: the teacher stays at its initialisation (a control)",
        "Null control for the learning itself: if the meta reward carries information the teacher uses, a teacher "
        "frozen at its initialisation collects worse data than the learned one; if it does as well, what the "
        "variants change is the data's spread, not what the teacher learns.",
        _frozen),
    "normalised-reward": Variant(
        "normalised meta reward", "`meta.normalize_meta_reward=true`",
        "The meta reward has no baseline and its scale grows with the returns; a running mean/std removes the "
        "bias (a baseline for REINFORCE) and keeps the step size constant over training.",
        lambda cfg: ["meta.normalize_meta_reward=true"]),
    "ddpg-update-ratio": Variant(
        "DDPG's update ratio", "`run.train_steps` = half the cycle's stored steps (DDPG's 50 per 100), "
                               "look-ahead updates unchanged",
        "The paper schedule gives the Meta student a third of DDPG's updates per stored step (50 per 300 on "
        "Hopper, 500 per 3,000 on HalfCheetah); part of Meta's gap is an under-trained student, not worse data.",
        _ddpg_ratio),
    "student-from-lookahead": Variant(
        "student from pi'", "`meta.student_from=lookahead`",
        "The look-ahead's updates on D0 are thrown away each cycle; starting the student's update from pi' "
        "keeps them (more updates per sample, on the freshest data) at no extra samples.",
        lambda cfg: ["meta.student_from=lookahead"]),
    "log-std-floor": Variant(
        "log-std floor -2.3", f"`meta.min_log_std={LOG_STD_FLOOR}` (preset -5: sigma >= 0.1 instead of 0.007)",
        "The teacher's log-std drifts to its floor (sigma 0.007), leaving D0 nearly deterministic; a floor at "
        "TD3's noise level keeps a minimum of exploration that the mean network can still steer.",
        lambda cfg: [f"meta.min_log_std={LOG_STD_FLOOR}"]),
    "fresh-baseline": Variant(
        "fresh R_hat(pi)", "`meta.baseline=fresh` (a D2 rollout of the updated student, stored and counted)",
        "With the preset's baseline the meta reward is R(pi'_t) - R(pi'_(t-1)): mostly the student's own progress "
        "between cycles, not D0's effect; R(pi'_t) - R(pi_t) from a fresh rollout is the improvement that D0 "
        "caused, a less confounded signal (at 3/5 of the D0 share of stored steps on Hopper).",
        lambda cfg: ["meta.baseline=fresh"]),
    "two-d1-envs": Variant(
        "2 D1 envs", "`meta.eval_envs=2` (R_hat the mean over two fresh-reset rollouts; D1 stored and counted)",
        "R_hat from one rollout is a noisy estimate; the mean of two cuts the meta reward's variance, at the "
        "price of fewer D0 samples and student updates per stored step.",
        lambda cfg: ["meta.eval_envs=2"]),
    # Combinations, written after the single changes above had run on both tasks.
    "schedule": Variant(
        "update ratio + 1 teacher step", "DDPG's update ratio and `meta.teacher_steps=1` (Hopper's preset has "
                                         "one teacher step: there this is the update-ratio cell)",
        "The two changes that helped alone act on different parts of Algorithm 1 (how much the student trains per "
        "sample; whether the teacher's log-std collapses), so their gains add on HalfCheetah: above either alone "
        "(2,955 and 3,372), with the log-std off its floor, where the update ratio alone left 3 of 8 seeds at it.",
        _combined(_ddpg_ratio, _one_step)),
    "schedule-frozen": Variant(
        "update ratio with a frozen teacher", "DDPG's update ratio and `meta.lr=0` (a control for the combination)",
        "Null control for the learning in the combined schedule: the frozen teacher did as well as the learned "
        "one under the paper schedule on both tasks; if REINFORCE adds nothing under the better schedule either, "
        "this cell equals the combination's, and what helps is the schedule, not the learned exploration.",
        _combined(_ddpg_ratio, _frozen)),
}
