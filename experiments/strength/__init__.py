"""The students at the field's strength: reference implementations run unchanged beside ours on the same tasks and
budgets, by hand, never in CI. ``cleanrl``: CleanRL's TD3 and SAC files in a venv of their own
outside the repository (``python -m experiments.strength.cleanrl setup|run``)."""
