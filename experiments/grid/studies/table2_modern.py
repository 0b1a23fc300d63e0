from experiments.grid.studies import Study

STUDY = Study("table2-modern", "reproduce",
              "a first look at the modern preset: Meta against DDPG's Gaussian noise 0.1 on IDP and Hopper, 30k steps, "
              "8 seeds, MJX (results/modern/)",
              {"preset": "modern", "tasks": "inverted_double_pendulum,hopper", "methods": "meta-independent,ddpg-normal",
               "steps": 30_000, "overrides": ["run.eval_every=1500"]})
