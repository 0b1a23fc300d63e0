from experiments.grid.studies import Study
from experiments.grid.studies.exploration_hard_pilot import budgets

# SAC with pink sampling noise at the paper preset on MountainCarContinuous: the entry the pilot lacks for the rule
# that picks the hard benchmark's preset (results/exploration-hard-modern-check/NOTES.md compares each entry's
# modern-preset return with its paper-preset one). The pilot's options, seeds (base 7000, never judged) and budget;
# SAC's own policy, the student's baseline, is planned beside it as every benchmark plans it.
TASKS = ("mountain_car_continuous",)

STUDY = Study("exploration-hard-pilot-sac-pink", "benchmark",
              "the hard-exploration pilot's missing entry: SAC with pink noise (and SAC's own policy) on "
              "MountainCarContinuous at the paper preset, 5 seeds from base seed 7000 "
              "(results/exploration-hard-pilot-sac-pink/)",
              {"name": "exploration-hard-pilot-sac-pink", "tasks": ",".join(TASKS), "students": "sac",
               "strategies": "sac-own,sac-pink", "seeds": 5, "seed": 7000,
               "anchors": "results/normalisation-hard.json", **budgets(TASKS)})
