"""The commands, each ``python -m experiments.<name>`` (and the ``metapg-*`` console scripts): ``run``, ``sweep``,
``reproduce``, ``screen``, ``benchmark``, ``ablation``, ``artefacts``, ``aggregate``, ``normalisation``, ``verify``,
``export``, ``bench``, ``bench_replay``. What they share lives in subpackages: ``training`` (run arguments, size
checks, a finished run's files, grid cells), ``build`` (the artefacts: statistics, tables, figures) and
``benchmarks``."""
