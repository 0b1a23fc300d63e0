"""The paper's task x method grid: task and method names, each method's ``experiments.run`` options,
and the DDPG baseline each preset's Meta is compared against.

Shared by everything that runs or reads the grid (``experiments.reproduce``, ``experiments.build.cells``,
``experiments.build.tables``, ``experiments.build.figures``, ``experiments.artefacts``).
"""

from __future__ import annotations

# In the paper's Table 2 order.
TASKS = ("inverted_double_pendulum", "inverted_pendulum", "hopper", "pendulum", "halfcheetah", "reacher")
TASK_NAMES = {"pendulum": "Pendulum", "inverted_pendulum": "InvertedPendulum",
              "inverted_double_pendulum": "InvertedDoublePendulum", "hopper": "Hopper",
              "halfcheetah": "HalfCheetah", "reacher": "Reacher"}
# Grid method name -> experiments.run options.
METHODS = {
    "meta-independent": ["--method=meta", "--teacher=independent"],
    "meta-variance": ["--method=meta", "--teacher=variance"],
    "ddpg-paramnoise": ["--method=ddpg", "--noise=adaptive-param"],
    "ddpg-normal": ["--method=ddpg", "--noise=normal"],
    # TD3's own exploration: Gaussian action noise 0.1 (Fujimoto et al. 2018; the paper preset's normal noise is 0.2).
    "td3-normal": ["--method=ddpg", "--noise=normal", "--set", "noise.stddev=0.1"],
    # Colored (pink, beta 1) noise at TD3's scale 0.1 (Eberhard et al., 2023), and FastTD3's per-episode scales
    # sigma ~ U[0.001, 0.4] (metapg_jax/strategies/pink.py, mixed.py).
    "td3-pink": ["--method=ddpg", "--noise=pink", "--set", "noise.stddev=0.1"],
    "td3-mixed": ["--method=ddpg", "--noise=mixed"],
    # SAC explores with its own policy, its sampling noise white or colored (metapg_jax/strategies/own.py).
    "sac-own": ["--method=own"],
    "sac-pink": ["--method=own", "--noise=pink"],
}
METHOD_NAMES = {"meta-independent": "Meta (independent)", "meta-variance": "Meta (variance)",
                "ddpg-paramnoise": "DDPG (param noise)", "ddpg-normal": "DDPG (normal noise)",
                "td3-normal": "TD3 (normal noise)", "td3-pink": "TD3 (pink noise)", "td3-mixed": "TD3 (mixed scales)",
                "sac-own": "SAC (own policy)", "sac-pink": "SAC (pink noise)"}
META, BASELINE = "meta-independent", "ddpg-paramnoise"
# The DDPG each preset's Meta is compared against: the paper's baseline (adaptive parameter noise), and
# for the modern preset its own exploration (Gaussian action noise 0.1, see metapg_jax/strategies/noise.py); the tuned
# preset's DDPG is the paper preset's.
BASELINES = {"paper": BASELINE, "modern": "ddpg-normal", "tuned": BASELINE}
# Each student's grid: its methods (a method's options plus ``--student=<student>`` for a student other
# than DDPG) and the baseline its Meta is compared against, whatever the preset: for TD3, TD3 with its
# own Gaussian exploration noise.
GRIDS = {"ddpg": ("meta-independent", "meta-variance", "ddpg-paramnoise", "ddpg-normal"),
         "td3": ("meta-independent", "td3-normal", "td3-pink", "td3-mixed"),
         "sac": ("sac-own", "sac-pink")}
STUDENT_BASELINES = {"td3": "td3-normal", "sac": "sac-own"}
# The student of a grid method that only one student's grid has (the others: DDPG's).
STUDENT_OF = {m: student for student, methods in GRIDS.items() if student != "ddpg" for m in methods
              if m not in GRIDS["ddpg"]}
STUDENT_NAMES = {"ddpg": "DDPG", "td3": "TD3", "sac": "SAC"}


def noise_methods(methods) -> list[str]:
    """The methods among ``methods`` that explore with noise, not a teacher (``--method=ddpg`` or ``own``)."""
    return [m for m in methods if {"--method=ddpg", "--method=own"} & set(METHODS.get(m, ()))]


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
