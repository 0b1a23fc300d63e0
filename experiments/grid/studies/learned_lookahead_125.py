from experiments.grid.studies import Study

STUDY = Study("learned-lookahead-125", "benchmark",
              "what the meta reward measures: the fixed-D0 controls with a look-ahead of 125 updates, HalfCheetah, 60k "
              "steps, 10 seeds from base seed 3000 (results/learned/lookahead/steps-125/)",
              {"name": "learned-lookahead-125", "results_dir": "results/learned/lookahead/steps-125", "tasks": "halfcheetah",
               "students": "td3", "baseline": ["td3=control-fixed"], "strategies": "control-uniform,control-noiseless",
               "seed": 3000, "steps": 60_000, "overrides": ["meta.lookahead_steps=125"]})
