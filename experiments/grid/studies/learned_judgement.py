from experiments.grid.studies import Study

STUDY = Study("learned-judgement", "benchmark",
              "the two screened variants judged on fresh seeds against the best fixed exploration chosen in advance, six "
              "tasks, 300k steps, 10 seeds from base seed 2000 (results/learned/judgement/)",
              {"name": "learned-judgement", "results_dir": "results/learned/judgement", "seed": 2000,
               "baseline": ["td3=td3-paramnoise,sac=sac-own"], "strategies": "learned-paired,learned-residual"})
