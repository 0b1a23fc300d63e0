from experiments.grid.studies import Study

STUDY = Study("table2", "reproduce",
              "the paper's Table 2 on MJX: DDPG's four methods x six tasks at the paper's budgets, 8 seeds (results/)")
