"""The shared design of the meta reward's signal check (results/learned/signal/): one benchmark grid per reward
variant, each holding the four fixed-D0 controls of the shared cycle (nothing in D0 learns) on the same tasks,
budgets and seeds, so that ``python -m experiments.analysis.signal`` can set each variant's reward beside what each
D0 does to the student. The studies are ``learned_signal_<variant>.py``; this module is their common part (a
module whose name starts with an underscore holds no study)."""

# MountainCarContinuous and two DeepMind Control tasks of the hard set whose returns are off the floor for TD3 at
# the paper preset's networks (the hard-exploration pilot: ball_in_cup-catch and reacher-hard; cartpole-swingup_sparse
# scored 0 for every entry and would leave nothing to rank), and one dense task where the D0s are known to differ
# (HalfCheetah: uniform D0 above D0 with noise 0.1 at 60k steps, results/learned/lookahead/).
TASKS = ("mountain_car_continuous", "dmc:ball_in_cup-catch", "dmc:reacher-hard", "halfcheetah")
# Budgets: whole cycles of the shared cycle (750 stored steps), evaluated every two cycles.
CYCLE = 750
STEPS = {"mountain_car_continuous": 49_500, "dmc:ball_in_cup-catch": 99_000, "dmc:reacher-hard": 99_000,
         "halfcheetah": 60_000}
EVAL_EVERY = 2 * CYCLE
SEEDS, SEED = 8, 9000  # base seed 9000: used by no other grid


def settings(variant: str, overrides: tuple[str, ...]) -> dict:
    """The benchmark options of the variant's grid (``experiments.grid.studies.Study.settings``)."""
    return {"name": f"learned-signal-{variant}", "results_dir": f"results/learned/signal/{variant}",
            "tasks": ",".join(TASKS), "students": "td3", "baseline": ["td3=control-fixed"],
            "strategies": "control-uniform,control-pink,control-noiseless", "seeds": SEEDS, "seed": SEED,
            "steps": STEPS["dmc:reacher-hard"], "task_steps": [f"{t}={n}" for t, n in STEPS.items()],
            "task_set": [f"{t}:run.eval_every={EVAL_EVERY}" for t in TASKS], "overrides": list(overrides)}

