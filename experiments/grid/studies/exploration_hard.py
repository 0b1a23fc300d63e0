from experiments.grid.studies import Study
from experiments.grid.studies.exploration_hard_pilot import TASKS

# The exploration benchmark where exploration decides the outcome (results/exploration-hard/): the pilot's seven tasks
# at MaxInfoRL's budgets (cut to whole cycles, below), every entry the issue names, the paper preset (the rule of
# results/exploration-hard-modern-check/NOTES.md: no entry gains 0.1 of MountainCarContinuous's range at the modern
# preset), MuJoCo's C engine, fresh seeds (base 8000: used by no earlier grid).
#
# Seeds by power (results/exploration-hard-pilot/seeds.md, declared before any cell runs): per task the fewest seeds,
# at least 10, whose first Holm step of 42 comparisons detects 0.1 of the task's range with 80% power, given the
# pilot's pooled seed std; at most what the cost cap (~15 CPU-hours for the grid) leaves. That is 10 on
# MountainCarContinuous, cartpole-swingup_sparse, finger-turn_hard and hopper-hop and 13 on pendulum-swingup;
# ball_in_cup-catch and reacher-hard would need more than 40, and the cap leaves them the rule's minimum, 10 (which
# detect about 0.42 and 0.36 of their ranges: their verdicts can only find large differences, and say so).
SEEDS = {"dmc:pendulum-swingup": 13}
# Budgets: the pilot's (MaxInfoRL's 50k, 250k and 500k), each cut to whole cycles of the tuned teacher (300 stored env
# steps; the other entries' cycles of 100 divide it) and to at least 50 evaluations a whole number of cycles apart:
# (budget, evaluated every) 49,500 / 900 (55 evaluations), 249,600 / 4,800 (52) and 499,200 / 9,600 (52); each
# within 1% below the pilot's budget. A final return averages the last 5 evaluations.
STEPS = {"mountain_car_continuous": (49_500, 900), "dmc:finger-turn_hard": (499_200, 9_600),
         "dmc:hopper-hop": (499_200, 9_600)}
DEFAULT = (249_600, 4_800)
STRATEGIES = ("td3-normal", "td3-ou", "td3-paramnoise", "td3-pink", "td3-mixed", "td3-random", "meta-tuned",
              "sac-own", "sac-pink")

STUDY = Study("exploration-hard", "benchmark",
              "the exploration benchmark on the hard set: TD3's and SAC's strategies on MountainCarContinuous and six "
              "DeepMind Control tasks at MaxInfoRL's budgets, 10-13 seeds by power from base seed 8000, C engine "
              "(results/exploration-hard/)",
              {"name": "exploration-hard", "tasks": ",".join(TASKS), "students": "td3,sac",
               "strategies": ",".join(STRATEGIES), "seeds": 10, "seed": 8000,
               "task_seeds": [f"{t}={n}" for t, n in SEEDS.items()],
               "anchors": "results/normalisation-hard.json", "steps": DEFAULT[0],
               "task_steps": [f"{t}={n}" for t, (n, _) in STEPS.items()],
               "task_set": [f"{t}:run.eval_every={STEPS.get(t, DEFAULT)[1]}" for t in TASKS]})
