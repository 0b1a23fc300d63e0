"""The paper's task x method grid: its tasks (``tasks``, from their specs in envs) and method names, each
method's ``experiments.run`` options,
and the DDPG baseline each preset's Meta is compared against; the exploration benchmark's strategies per
student (``STRATEGIES``).

Shared by everything that runs or reads the grid (``experiments.reproduce``, ``experiments.analysis.cells``,
``experiments.analysis.tables``, ``experiments.analysis.render.figures``, ``experiments.artefacts``, ``experiments.benchmark``).
"""

from __future__ import annotations

import re

from experiments.grid.spec import method

# The cycle of the learned-exploration variants and their controls on every task: D0 250 steps; D1 and the paired
# rollout of pi 125 steps from the same resets in 2 envs each; 750 stored steps, a third of them D0 (as the paper
# preset's cycle); a look-ahead of half an update per D0 step (as the paper preset on every task); 20 cycles per
# 15,000-step evaluation interval. The tuned preset adds one teacher step and student updates for half the cycle.
PAIRED_CYCLE = ("meta.baseline=paired", "meta.eval_envs=2", "meta.explore_steps=250", "meta.eval_steps=125",
                "meta.lookahead_steps=125")
# Grid method name -> how its cells explore (``experiments.grid.spec.Method``: experiments.run's --method, its
# shortcuts, --set overrides, a preset of its own).
METHODS = {
    "meta-independent": method("meta", teacher="independent"),
    "meta-variance": method("meta", teacher="variance"),
    "ddpg-paramnoise": method("ddpg", noise="adaptive-param"),
    "ddpg-normal": method("ddpg", noise="normal"),
    # TD3's own exploration: Gaussian action noise 0.1 (Fujimoto et al. 2018; the paper preset's normal noise is 0.2).
    "td3-normal": method("ddpg", "noise.stddev=0.1", noise="normal"),
    # Colored (pink, beta 1) noise at TD3's scale 0.1 (Eberhard et al., 2023), and FastTD3's per-episode scales
    # sigma ~ U[0.001, 0.4] (metapg_jax/strategies/pink.py, mixed.py).
    "td3-pink": method("ddpg", "noise.stddev=0.1", noise="pink"),
    "td3-mixed": method("ddpg", noise="mixed"),
    # Ornstein-Uhlenbeck noise with OpenAI baselines' (2018) theta 0.15 and dt 0.01 (the noise group's defaults,
    # docs/strategies.md) at TD3's scale sigma 0.1, so that TD3's action noises differ in their process only.
    "td3-ou": method("ddpg", "noise.stddev=0.1", noise="ou"),
    # Adaptive parameter noise (Plappert et al., 2018) with the action-space target 0.1, TD3's Gaussian scale
    # (the paper preset's DDPG baseline, ddpg-paramnoise, targets baselines' 0.2).
    "td3-paramnoise": method("ddpg", "noise.stddev=0.1", noise="adaptive-param"),
    # The tuned teacher: the screen's schedule (--preset=tuned), whatever the grid's preset.
    "meta-tuned": method("meta", preset="tuned", teacher="independent"),
    # SAC explores with its own policy, its sampling noise white or colored (metapg_jax/strategies/own.py).
    "sac-own": method("own"),
    "sac-pink": method("own", noise="pink"),
    # The paper's teacher collecting a SAC student's data (the student itself never acts during training).
    "sac-meta": method("meta", teacher="independent"),
    # Learned exploration, second attempt (results/learned/README.md; LEARNED): teacher designs and controls under
    # the tuned schedule (preset tuned) with the paired meta reward, all in one cycle (PAIRED_CYCLE).
    # The paper's teacher with the paired meta reward, learning at 1e-3 (as the residual teacher, below).
    "learned-paired": method("meta", "meta.lr=1e-3", *PAIRED_CYCLE, preset="tuned", teacher="independent"),
    # The residual teacher starts as the student with TD3's Gaussian noise 0.1 (log-std -2.3), and learns at 1e-3:
    # at the paper's 1e-4, 400 one-step cycles move each weight by at most ~0.04 (Adam's steps are ~lr).
    "learned-residual": method("meta", "meta.init_log_std=-2.3", "meta.lr=1e-3", *PAIRED_CYCLE, preset="tuned",
                               teacher="residual"),
    "learned-bandit": method("meta", *PAIRED_CYCLE, preset="tuned", teacher="bandit"),
    # Controls in the same cycle: the paper's teacher frozen at its initialisation; D0 uniformly random; the student
    # with TD3's Gaussian noise 0.1, or with pink noise at that scale (a colored D0, bandit.beta 1: a new sequence
    # per exploring episode, as td3-pink's); the student alone.
    "control-frozen": method("meta", "meta.lr=0", *PAIRED_CYCLE, preset="tuned", teacher="independent"),
    "control-uniform": method("meta", *PAIRED_CYCLE, preset="tuned", teacher="uniform"),
    "control-fixed": method("meta", "bandit.scales=0.1", *PAIRED_CYCLE, preset="tuned", teacher="bandit"),
    "control-pink": method("meta", "bandit.scales=0.1", "bandit.beta=1", *PAIRED_CYCLE, preset="tuned",
                           teacher="bandit"),
    "control-noiseless": method("meta", "bandit.scales=0", *PAIRED_CYCLE, preset="tuned", teacher="bandit"),
    # Uniformly random actions while TD3 trains (--method=random): how much any directed exploration matters on a
    # task (the benchmark of the hard tasks' control).
    "td3-random": method("random"),
}
# The grid methods that run under a preset of their own, overriding the grid's (``CellSpec.run_preset``).
METHOD_PRESETS = {name: m.preset for name, m in METHODS.items() if m.preset}
METHOD_NAMES = {"meta-independent": "Meta (independent)", "meta-variance": "Meta (variance)",
                "ddpg-paramnoise": "DDPG (param noise)", "ddpg-normal": "DDPG (normal noise)",
                "td3-normal": "TD3 (normal noise)", "td3-pink": "TD3 (pink noise)", "td3-mixed": "TD3 (mixed scales)",
                "sac-own": "SAC (own policy)", "sac-pink": "SAC (pink noise)", "td3-ou": "TD3 (OU noise)",
                "td3-paramnoise": "TD3 (param noise)", "meta-tuned": "Meta (tuned)",
                "sac-meta": "SAC + Meta (independent)", "learned-paired": "Meta (paired reward)",
                "learned-residual": "residual teacher", "learned-bandit": "bandit over noise scales",
                "control-frozen": "control: frozen teacher", "control-uniform": "control: uniform D0", "control-fixed": "control: D0 with noise 0.1",
                "control-pink": "control: D0 with pink noise 0.1",
                "control-noiseless": "control: noiseless D0", "td3-random": "TD3 (uniformly random actions)"}
META, BASELINE = "meta-independent", "ddpg-paramnoise"
# The DDPG each preset's Meta is compared against: the paper's baseline (adaptive parameter noise), and
# for the modern preset its own exploration (Gaussian action noise 0.1, see metapg_jax/strategies/noise.py); the tuned
# preset's DDPG is the paper preset's.
BASELINES = {"paper": BASELINE, "modern": "ddpg-normal", "tuned": BASELINE}
# Each student's reproduction grid (``experiments.reproduce --student``): its methods (a method's options plus
# ``--student=<student>`` for a student other than DDPG) and the baseline its Meta is compared against, whatever
# the preset: for TD3, TD3 with its own Gaussian exploration noise; for SAC, SAC with its own policy.
# Every other strategy of a student is the exploration benchmark's (STRATEGIES).
GRIDS = {"ddpg": ("meta-independent", "meta-variance", "ddpg-paramnoise", "ddpg-normal"),
         "td3": ("meta-independent", "td3-normal"),
         "sac": ("sac-meta", "sac-own")}
STUDENT_BASELINES = {"td3": "td3-normal", "sac": "sac-own"}
# Each student's Gaussian-noise exploration: what a grid's estimate scales one task's cost to another's by
# (experiments.grid.estimate).
GAUSSIAN = {"ddpg": "ddpg-normal", **STUDENT_BASELINES}
# The exploration benchmark (experiments.benchmark): each student's strategies, its Gaussian-noise baseline
# (STUDENT_BASELINES) first, every other one judged against it. TD3: Gaussian, OU, adaptive parameter noise,
# colored noise, per-episode scales, the paper's teacher and the tuned teacher; SAC: its own policy with white
# or colored sampling noise, and the paper's teacher.
STRATEGIES = {"td3": ("td3-normal", "td3-ou", "td3-paramnoise", "td3-pink", "td3-mixed", "meta-independent",
                      "meta-tuned"),
              "sac": ("sac-own", "sac-pink", "sac-meta")}
# Each student's learned-exploration variants and their controls (results/learned/README.md, second attempt).
LEARNED_METHODS = ("learned-paired", "learned-residual", "learned-bandit", "control-frozen", "control-uniform",
                   "control-fixed", "control-pink", "control-noiseless")
LEARNED = {"td3": LEARNED_METHODS, "sac": LEARNED_METHODS}
# Entries of the benchmark only when named (``experiments.benchmark --strategies``), never in its default plan: the
# learned variants, and TD3 with uniformly random actions (a control for the hard tasks).
NAMED_ONLY = {"td3": (*LEARNED_METHODS, "td3-random"), "sac": LEARNED_METHODS}
# The student of a grid method that only one student's grid or strategies have (the others: DDPG's).
STUDENT_OF = {m: student for table in (GRIDS, STRATEGIES) for student, methods in table.items() if student != "ddpg"
              for m in methods if m not in GRIDS["ddpg"]}
STUDENT_NAMES = {"ddpg": "DDPG", "td3": "TD3", "sac": "SAC"}


def tasks() -> tuple[str, ...]:
    """The grid's tasks: the paper's, in its Table 2 order (``envs.paper_tasks``: each task's spec)."""
    import envs  # brax on import: only when the tasks are asked for

    return envs.paper_tasks()


def task_name(task: str) -> str:
    """How tables name a task: its spec's display name (``envs.display_name``; a ``gym:<Id>`` task's gymnasium id
    with its arguments), or the name itself for a task this code does not know."""
    import envs  # brax on import: only when a name is asked for

    return envs.display_name(task) if task in envs.TASKS or envs.is_gym_task(task) else task


def task_folder(task: str) -> str:
    """A task's folder name in a grid (``<runs>/<preset>/<task>/<method>``): the task itself, or a ``gym:`` task
    with everything but letters, digits and ``_.=+-`` made a hyphen (as ``experiments.run`` names its default
    folder: ``gym:Ant-v5(ctrl_cost_weight=0.1)`` -> ``gym-Ant-v5-ctrl_cost_weight=0.1``)."""
    return re.sub(r"[^\w.=+-]+", "-", task).strip("-")


def noise_methods(methods) -> list[str]:
    """The methods among ``methods`` that explore with noise, not a teacher (``--method=ddpg`` or ``own``)."""
    return [m for m in methods if m in METHODS and METHODS[m].explorer in ("ddpg", "own")]


def methods_for(student: str = "ddpg") -> tuple[str, ...]:
    """The grid methods of ``student`` (``experiments.reproduce --student``)."""
    if student not in GRIDS:
        raise ValueError(f"no grid for student {student!r}; students with a grid: {', '.join(GRIDS)}")
    return GRIDS[student]


def baseline_for(preset: str, student: str = "ddpg") -> str:
    """Grid method name of the baseline of ``preset``'s comparisons (Welch test, thresholds, figures)."""
    if preset not in BASELINES:
        raise ValueError(f"unknown preset {preset!r}; valid presets: {', '.join(BASELINES)}")
    methods_for(student)
    return STUDENT_BASELINES.get(student, BASELINES[preset])


def grid_label(preset: str, student: str = "ddpg") -> str:
    """How titles name a grid: 'paper preset', or 'paper preset, TD3 student' for a student other than DDPG."""
    return f"{preset} preset" if student == "ddpg" else f"{preset} preset, {STUDENT_NAMES.get(student, student)} student"
