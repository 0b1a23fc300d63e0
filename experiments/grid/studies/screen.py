from experiments.grid.studies import Study

STUDY = Study("screen", "screen",
              "Algorithm 1's knobs one at a time on Hopper and HalfCheetah, 300k steps, 8 seeds, C engine "
              "(results/screen/)")
