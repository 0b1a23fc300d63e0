from experiments.grid.studies import Study

# The pilot of the hard-exploration benchmark: its spreads choose the benchmark's seed counts
# (experiments.analysis.power.seeds_for) and show which tasks separate entries at all; its seeds (base 7000) are
# never judged. Budgets as MaxInfoRL's (50k MountainCarContinuous, 250k the DMC tasks, 500k finger-turn_hard and
# hopper-hop); 50 evaluations per seed, so a final return (the last 10% of evaluations) averages 5 of them.
TASKS = ("mountain_car_continuous", "dmc:cartpole-swingup_sparse", "dmc:ball_in_cup-catch", "dmc:reacher-hard",
         "dmc:pendulum-swingup", "dmc:finger-turn_hard", "dmc:hopper-hop")
STEPS = {"mountain_car_continuous": 50_000, "dmc:finger-turn_hard": 500_000, "dmc:hopper-hop": 500_000}
DEFAULT_STEPS = 250_000
EVALUATIONS = 50


def budgets(tasks) -> dict:
    """The benchmark options of ``tasks``' budgets (``STEPS``, else ``DEFAULT_STEPS``) and evaluation intervals
    (``EVALUATIONS`` per seed): this pilot's, and those of a check on some of its tasks."""
    return {"steps": DEFAULT_STEPS, "task_steps": [f"{t}={n}" for t, n in STEPS.items() if t in tasks],
            "task_set": [f"{t}:run.eval_every={STEPS.get(t, DEFAULT_STEPS) // EVALUATIONS}" for t in tasks]}


STUDY = Study("exploration-hard-pilot", "benchmark",
              "the pilot of the hard-exploration benchmark: TD3 with Gaussian, pink and uniformly random actions, SAC "
              "with its own policy, on MountainCarContinuous and six DeepMind Control tasks at MaxInfoRL's budgets, 5 "
              "seeds from base seed 7000, C engine (results/exploration-hard-pilot/)",
              {"name": "exploration-hard-pilot", "tasks": ",".join(TASKS), "students": "td3,sac",
               "strategies": "td3-normal,td3-pink,td3-random,sac-own", "seeds": 5, "seed": 7000,
               "anchors": "results/normalisation-hard.json", **budgets(TASKS)})
