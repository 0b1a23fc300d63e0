from experiments.grid.studies import Study

STUDY = Study("learned-screen", "benchmark",
              "learned exploration, second attempt: TD3's teacher variants and controls against every fixed noise on "
              "Hopper and HalfCheetah, 300k steps, 10 seeds from base seed 1000 (results/learned/screen/)",
              {"name": "learned-screen", "results_dir": "results/learned/screen", "tasks": "hopper,halfcheetah",
               "students": "td3",
               "strategies": "td3-ou,td3-paramnoise,td3-pink,td3-mixed,meta-tuned,learned-paired,learned-residual,"
                             "learned-bandit,control-frozen,control-uniform,control-fixed,control-noiseless"})
