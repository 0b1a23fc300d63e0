from experiments.grid.studies import Study

STUDY = Study("table2-td3", "reproduce",
              "the paper's teacher on TD3 against TD3's Gaussian noise 0.1, four tasks, 300k steps, 8 seeds, C engine "
              "(results/td3/)",
              {"student": "td3", "physics": "mujoco", "steps": 300_000,
               "tasks": "inverted_double_pendulum,reacher,hopper,halfcheetah"})
