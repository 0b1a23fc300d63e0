"""Artefact building: the grids' cells and archive (``cells``, ``grid``), the statistics every table uses
(``stats``), and the tables, figures and plots built from stored runs (``benchmark``: the exploration benchmark's).
The commands in ``experiments/`` (``artefacts``, ``reproduce``, ``screen``, ``benchmark``, ``ablation``, ``aggregate``,
``normalisation``, ``verify``) drive them."""
