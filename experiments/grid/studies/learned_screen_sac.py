from experiments.grid.studies import Study

STUDY = Study("learned-screen-sac", "benchmark",
              "learned exploration, second attempt, on SAC: Hopper and HalfCheetah, 300k steps, 10 seeds from base seed "
              "1000 (results/learned/screen-sac/)",
              {"name": "learned-screen-sac", "results_dir": "results/learned/screen-sac", "tasks": "hopper,halfcheetah",
               "students": "sac", "strategies": "sac-pink,sac-meta,learned-paired"})
