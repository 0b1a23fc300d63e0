"""A finished run folder's files beyond the driver's record (``metapg_jax.host.driver``): ``summary.json`` (the
tables' final return), the exported policies, the visited-state sample and the plots, with the end-of-run lines."""

from __future__ import annotations

import os

from metapg_jax import config as config_lib

from experiments.training.args import run_label


def finalize(cfg: config_lib.Config, out: str, state, num_seeds: int, plot: bool = True, extra: dict | None = None):
    """Summary, plots, the exported policies and the visited-state sample, from a finished state."""
    from metapg_jax.host import metric_rows, runfiles
    from metapg_jax.host.policy import export_policies

    from experiments.analysis import stats

    rows = runfiles.read_jsonl(os.path.join(out, "metrics.jsonl"))
    summary = stats.run_summary(*metric_rows.curves(rows))
    summary.update({"method": cfg.run.method, "env": cfg.env.name, "preset": cfg.preset, "source": cfg.env.source,
                    "physics": cfg.env.physics,
                    **(extra or {})})
    runfiles.write_json_atomic(os.path.join(out, "summary.json"), summary)
    export_policies(os.path.join(out, "policy.npz"), cfg, state.student.actor, state.normalizer)
    save_visits(os.path.join(out, "visits.npz"), state.visits)
    name = run_label(cfg)
    if plot:
        title = f"{name}, {cfg.preset} preset: {num_seeds} seeds"
        metric_rows.plot_learning_curve(rows, os.path.join(out, "learning_curve.png"), title)
        spec = cfg.explorer_spec
        if spec.cycle_panels and spec.cycle_metrics:  # (cycles.jsonl is written for cycle metrics only)
            from experiments.analysis.render.plots import plot_cycles

            plot_cycles(runfiles.read_jsonl(os.path.join(out, "cycles.jsonl")), spec.cycle_panels,
                        os.path.join(out, spec.plot_file), title)
    for i, (v, last) in enumerate(zip(summary["final_return_per_seed"], summary["last_eval_return_per_seed"])):
        print(f"seed {i}: final return {stats.fmt(v, 1)} (last evaluation {stats.fmt(last, 1)})")
    line = f"{name}: {stats.describe_final(summary)}, {summary['env_steps']:,} env steps"
    if "env_steps_per_second_total" in summary:
        line += (f"; {summary['env_steps_per_second_total']:,.0f} env steps/s total, "
                 f"compile {summary['compile_seconds']:.1f} s, peak RSS {summary['peak_rss_mib']:,.0f} MiB")
    print(line)
    return summary


def save_visits(path: str, visits) -> None:
    """The bounded sample of visited states per seed (for the state-visitation figure), atomically."""
    import dataclasses

    import numpy as np

    from metapg_jax.host.runfiles import savez_atomic

    savez_atomic(path, {f.name: np.asarray(getattr(visits, f.name)) for f in dataclasses.fields(visits)})
