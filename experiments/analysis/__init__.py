"""The analysis of stored grids, in two parts. Computing, here: the cells and their archive (``cells``), the
statistics (``stats``: final returns, tests, corrections, verdicts, bootstrap aggregates), Table 2's rows,
verdict families, steps to threshold and comparisons (``tables``), what the explorers stored (``behaviour``), the
exploration benchmark's rows, aggregate, curves and cost (``benchmark``) and the learned explorers' diagnostics
(``learned``). Rendering, in ``render/``: markdown, JSON and figures written from those (``tables``, ``benchmark``,
``learned``, ``figures``, ``plots``, ``readme``). The commands in ``experiments/`` (``artefacts``, ``reproduce``,
``screen``, ``benchmark``, ``ablation``, ``aggregate``, ``normalisation``, ``verify``) drive them."""
