from experiments.grid.studies import Study
from experiments.grid.studies._signal import settings

# The meta reward's signal on fixed D0s: the second attempt's paired reward (R_hat(pi') - R_hat(pi) from the same
# resets), the shared cycle as it is.
STUDY = Study("learned-signal-paired", "benchmark",
              "the meta reward's signal, paired reward: the four fixed-D0 controls on MountainCarContinuous, "
              "ball_in_cup-catch, reacher-hard and HalfCheetah, 8 seeds from base seed 9000 "
              "(results/learned/signal/paired/)",
              settings("paired", ()))
