"""The training commands' shared machinery (``experiments.run``, ``experiments.sweep``,
``experiments.reproduce``): run arguments to a validated config (``args``), size checks before compile
(``memory``), and a run folder's final files (``finish``)."""
