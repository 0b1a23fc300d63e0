from experiments.grid.studies import Study

STUDY = Study("exploration", "benchmark",
              "the exploration benchmark: TD3's and SAC's strategies on six tasks, 300k steps, 10 seeds from base seed "
              "1000, C engine (results/exploration/)")
