from experiments.grid.studies import Study

STUDY = Study("tuned", "reproduce",
              "the screen's schedule as a preset: the tuned teacher and both DDPG noises at the paper's budgets, 8 seeds "
              "from base seed 100, C engine (results/tuned/)",
              {"preset": "tuned", "physics": "mujoco", "seed": 100, "results_dir": "results",
               "methods": "meta-independent,ddpg-paramnoise,ddpg-normal"})
