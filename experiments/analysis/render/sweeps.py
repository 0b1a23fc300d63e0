"""A sweep's summary (``experiments.sweep``): ``summary.md``, ``summary.json`` and ``sweep.png``."""

from __future__ import annotations

import os

from experiments.analysis.render.plots import plot_sweep
from experiments.analysis.stats import FINAL_DEFINITION, fmt
from experiments.analysis.sweeps import summary_rows
from metapg_jax.host import runfiles


def write_summary(out: str, settings, configs, plot: bool = True) -> list[dict]:
    """Writes the sweep's ``summary.md``, ``summary.json`` and (``plot``) ``sweep.png`` in ``out`` and prints its
    line; returns ``experiments.analysis.sweeps.summary_rows``."""
    rows = summary_rows(out, settings, configs)
    fields = list(settings[0])
    md = ["# Sweep: final evaluation return per setting", "",
          f"- {FINAL_DEFINITION}; ± is the standard deviation over seeds, CI the 95% t interval of the mean.",
          "- **best**: the highest mean among finished settings with finite parameters.", "",
          "| setting | " + " | ".join(f"`{f}`" for f in fields) + " | final return | 95% CI | seeds | |",
          "|---|" + "---|" * len(fields) + "---|---|---|---|"]
    for e in rows:
        final = f"{fmt(e['mean'])} ± {fmt(e['std'])}" if "mean" in e else (
            "non-finite parameters" if not e["finite"] else "not run" if not e.get("per_seed") else "n/a")
        ci = f"[{fmt(e['ci95'][0])}, {fmt(e['ci95'][1])}]" if e.get("ci95") else ""
        note = "**best**" if e.get("best") else ("incomplete" if e.get("per_seed") and not e["complete"] else "")
        md.append(f"| {e['setting']} | " + " | ".join(e["values"][f] for f in fields) +
                  f" | {final} | {ci} | {e['seeds']} | {note} |")
    with open(os.path.join(out, "summary.md"), "w") as f:
        f.write("\n".join(md) + "\n")
    runfiles.write_json_atomic(os.path.join(out, "summary.json"), {"final_definition": FINAL_DEFINITION,
                                                                    "settings": rows})
    if plot:
        plot_sweep(rows, fields, os.path.join(out, "sweep.png"))
    best = next((e for e in rows if e.get("best")), None)
    print(f"summary: {out}/summary.md" + (f"; best: setting {best['setting']} "
                                           f"({', '.join(f'{k}={v}' for k, v in best['values'].items())}): "
                                           f"{fmt(best['mean'])} ± {fmt(best['std'])}" if best else ""), flush=True)
    return rows
