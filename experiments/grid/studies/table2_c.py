from experiments.grid.studies import Study

# The cheaper tasks first; the order changes nothing else.
STUDY = Study("table2-c", "reproduce",
              "Table 2 on MuJoCo's C engine (Pendulum on its JAX physics): DDPG's four methods x six tasks at the "
              "paper's budgets, 10 seeds from base seed 4000 (results/table2-c/)",
              {"physics": "mujoco", "seeds": 10, "seed": 4000,
               "tasks": "pendulum,reacher,hopper,inverted_double_pendulum,inverted_pendulum,halfcheetah",
               "runs_dir": "runs/table2-c", "results_dir": "results/table2-c"})
