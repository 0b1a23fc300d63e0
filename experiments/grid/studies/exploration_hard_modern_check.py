from experiments.grid.studies import Study
from experiments.grid.studies.exploration_hard_pilot import budgets

# The pilot's entries, seeds and budgets on two of its tasks under the modern preset (256-256 networks, one update
# per env step, 25k random steps first): whether the cheaper paper preset keeps the strategies' order on the hard
# set, or leaves every entry at the floor where the modern one does not (#62, item 3). Cells comparable seed for
# seed with the pilot's (base seed 7000, never judged). SAC with pink sampling noise is an entry here and not in the
# pilot: pink-noise-rl's own example, SAC solving MountainCarContinuous with pink noise and not with white, is a check
# of our SAC and colored noise where the field has a number (#61 item 4).
TASKS = ("mountain_car_continuous", "dmc:cartpole-swingup_sparse")

STUDY = Study("exploration-hard-modern-check", "benchmark",
              "the hard-exploration pilot's entries and SAC with pink noise on MountainCarContinuous and "
              "cartpole-swingup_sparse under the modern preset, 5 seeds from base seed 7000, C engine "
              "(results/exploration-hard-modern-check/)",
              {"name": "exploration-hard-modern-check", "tasks": ",".join(TASKS), "students": "td3,sac",
               "strategies": "td3-normal,td3-pink,td3-random,sac-own,sac-pink", "seeds": 5, "seed": 7000,
               "preset": "modern", "anchors": "results/normalisation-hard.json", **budgets(TASKS)})
