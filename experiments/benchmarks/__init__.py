"""The benchmarks' measurements and records: training speed and seed scaling (``training``), env stepping
alone (``env_speed``), a sweep as one program (``sweep``), the README's main job (``main_job``), the engines
side by side (``engines``), the replay buffers (``replay``), the shared clock (``timing``) and the record
writing (``records``). The commands ``experiments.bench`` and ``experiments.bench_replay`` drive them."""
