"""The training commands' shared machinery (``experiments.run``, ``experiments.sweep``, ``experiments.reproduce``,
``experiments.screen``, ``experiments.benchmark``): run arguments to a validated config and the plug-ins they name
(``args``), size checks before compile (``memory``), a run folder's final files (``finish``), a grid's cells with
their record and launchers (``grid_cells``), and the screen's variants (``screen_variants``)."""
