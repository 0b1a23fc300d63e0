"""A sweep's numbers (``experiments.sweep``): each setting's final return over its seeds, from the sweep's
``metrics.jsonl``."""

from __future__ import annotations

import os

import numpy as np

from experiments.analysis.stats import final_returns, mean_std, t_interval
from metapg_jax.host import runfiles


def summary_rows(out: str, settings, configs) -> list[dict]:
    """Per setting: final return (experiments.analysis.stats: mean of each seed's last 10% of evaluations) mean ±
    std over seeds and the 95% t interval; a setting with non-finite parameters is flagged."""
    rows = runfiles.read_jsonl(os.path.join(out, "metrics.jsonl"))
    result = []
    for k, s in enumerate(settings):
        mine = [r for r in rows if r["setting"] == k]
        seeds = sorted({r["seed"] for r in mine})
        chunks = sorted({r["chunk"] for r in mine})
        entry = {"setting": k, "values": s, "seeds": len(seeds), "evaluations": len(chunks),
                 "complete": len(chunks) == configs[k].num_chunks, "finite": all(r.get("finite", True) for r in mine)}
        if mine:
            curve = np.full((len(seeds), len(chunks)), np.nan)
            for r in mine:
                curve[seeds.index(r["seed"]), chunks.index(r["chunk"])] = (
                    np.nan if r["eval_return"] is None else r["eval_return"])
            per_seed = final_returns(curve)
            entry["per_seed"] = [float(x) for x in per_seed]
            if entry["finite"] and np.isfinite(per_seed).all():
                entry["mean"], entry["std"] = mean_std(per_seed)
                mean, half = t_interval(per_seed)
                entry["ci95"] = [mean - half, mean + half] if len(per_seed) > 1 else None
        result.append(entry)
    ranked = [e for e in result if "mean" in e and e["complete"]]
    if ranked:
        max(ranked, key=lambda e: e["mean"])["best"] = True
    return result
