from experiments.grid.studies import Study
from experiments.grid.studies._signal import settings

# The meta reward's signal on fixed D0s: the counterfactual reward, the look-ahead on D0 alone (R_hat(pi') -
# R_hat(pi''), pi'' trained as long without D0).
STUDY = Study("learned-signal-counterfactual-d0", "benchmark",
              "the meta reward's signal, counterfactual reward with the look-ahead on D0: the four fixed-D0 controls "
              "on MountainCarContinuous, ball_in_cup-catch, reacher-hard and HalfCheetah, 8 seeds from base seed "
              "9000 (results/learned/signal/counterfactual-d0/)",
              settings("counterfactual-d0", ("meta.baseline=counterfactual",)))
