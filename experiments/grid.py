"""The paper's task x method grid: task and method names, each method's ``experiments.run`` options,
and the DDPG baseline each preset's Meta is compared against.

Shared by everything that runs or reads the grid (``experiments.reproduce``, ``experiments.cells``,
``experiments.tables``, ``experiments.figures``, ``experiments.artefacts``).
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
}
METHOD_NAMES = {"meta-independent": "Meta (independent)", "meta-variance": "Meta (variance)",
                "ddpg-paramnoise": "DDPG (param noise)", "ddpg-normal": "DDPG (normal noise)"}
META, BASELINE = "meta-independent", "ddpg-paramnoise"
# The DDPG each preset's Meta is compared against: the paper's baseline (adaptive parameter noise), and
# for the modern preset its own exploration (Gaussian action noise 0.1, see metapg_jax/config.py).
BASELINES = {"paper": BASELINE, "modern": "ddpg-normal"}


def baseline_for(preset: str) -> str:
    """Grid method name of the DDPG baseline of ``preset``'s comparisons (Welch test, thresholds, figures)."""
    if preset not in BASELINES:
        raise ValueError(f"unknown preset {preset!r}; valid presets: {', '.join(BASELINES)}")
    return BASELINES[preset]
