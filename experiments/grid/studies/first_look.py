from experiments.grid.studies import Study

STUDY = Study("first-look", "benchmark",
              "the new strategies and SAC on Hopper and HalfCheetah, 300k steps, 8 seeds, C engine (results/first-look/)",
              {"name": "first-look", "tasks": "hopper,halfcheetah", "students": "td3,sac",
               "strategies": "td3-normal,td3-pink,td3-mixed,meta-independent,sac-own,sac-pink", "seeds": 8, "seed": 0})
