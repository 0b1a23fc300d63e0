from experiments.grid.studies import Study
from experiments.grid.studies._signal import settings

# The meta reward's signal on fixed D0s: the counterfactual reward, the look-ahead on the replay buffer with D0 in
# it (D0's marginal value to the real update).
STUDY = Study("learned-signal-counterfactual-mix", "benchmark",
              "the meta reward's signal, counterfactual reward with the look-ahead on the buffer and D0: the four "
              "fixed-D0 controls on MountainCarContinuous, ball_in_cup-catch, reacher-hard and HalfCheetah, 8 seeds "
              "from base seed 9000 (results/learned/signal/counterfactual-mix/)",
              settings("counterfactual-mix", ("meta.baseline=counterfactual", "meta.lookahead_data=mix")))
