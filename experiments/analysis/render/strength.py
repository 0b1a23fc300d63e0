"""The strength comparison's files and command (``python -m experiments.analysis.strength``, whose module docstring
states what is compared and the rule): ``<name>.md``, ``<name>.json`` and ``<name>.png`` (the two sides' training
returns per chunk, mean over seeds)."""

from __future__ import annotations

import argparse
import datetime
import glob
import os
import sys

from experiments.analysis import strength
from experiments.analysis.stats import fmt


def markdown(name: str, result: dict) -> str:
    ours, ref = result["ours"], result["reference"]
    lines = [f"# {name}: ours beside {result['reference_label']}", "",
             f"Training-episode returns at {result['budget']:,} env steps per seed; a seed's final return is the mean "
             f"of its chunks' training returns over the last {result['final_fraction']:.0%} of the budget (the "
             f"reference's episodes binned into our chunks; `experiments/analysis/strength.py`). Ours: "
             f"`{result['ours_run']}`; {result['reference_label']}: `{result['reference_files']}`.", "",
             "| side | seeds | final return per seed | mean [95% CI] |", "|---|---|---|---|"]
    for label, side in (("ours", ours), (result["reference_label"], ref)):
        lines.append(f"| {label} | {len(side['finals'])} | {', '.join(fmt(x) for x in side['finals'])} | "
                     f"{fmt(side['mean'])} [{fmt(side['ci95'][0])}, {fmt(side['ci95'][1])}] |")
    ci = result["difference_ci95"]
    lines += ["", f"Difference (ours − {result['reference_label']}): {fmt(result['difference'])} [95% Welch CI "
                  f"{fmt(ci[0])}, {fmt(ci[1])}], {fmt(result['difference_in_std'])} pooled seed std "
                  f"({fmt(result['pooled_std'])}): **{result['verdict']}** (beyond it: a defect to find).", "",
              f"![training returns]({name}.png)", "",
              f"Built {result['built']} at commit `{result['commit']}`" +
              (" (uncommitted changes)" if result["dirty"] else "") + ".", ""]
    return "\n".join(lines)


def figure(name: str, result: dict, path: str) -> None:
    from experiments.analysis.render.figures import pyplot, save_figure

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 3.5))
    for label, side in (("ours", result["ours"]), (result["reference_label"], result["reference"])):
        ax.plot(result["chunk_ends"], side["curve"], label=label)
    ax.set_xlabel("env steps")
    ax.set_ylabel("training return (mean over seeds)")
    ax.set_title(name, fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, result)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    from experiments.analysis import cells
    from metapg_jax.host.provenance import record
    from metapg_jax.host.runfiles import json_numbers, write_json_atomic, write_text_atomic

    p = argparse.ArgumentParser(prog="python -m experiments.analysis.strength", description=strength.__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--reference", required=True, help="glob of the reference's per-seed CSVs (step,episodic_return)")
    p.add_argument("--reference-label", default="CleanRL", help="the reference's name (default CleanRL)")
    p.add_argument("--ours", required=True, help="our finished run folder (experiments.run --out)")
    p.add_argument("--name", required=True, help="the comparison's file names, e.g. td3-hopper")
    p.add_argument("--out", required=True, help="folder of the files")
    a = p.parse_args(argv)
    files = sorted(glob.glob(a.reference))
    run = cells.load_run(a.ours)
    why = ("--reference matches no file" if not files else f"--ours {a.ours}: no run with evaluations there"
           if run is None else f"--ours {a.ours} logged no train_return" if "train_return" not in run.behaviour
           else "")
    try:
        result = why or strength.compare([strength.read_episodes(f) for f in files], run.steps,
                                         run.behaviour["train_return"], run.budget)
    except ValueError as err:
        why = str(err)
    if why:
        print(f"error: {why}", file=sys.stderr)
        return 2
    prov = record()
    result.update(reference_label=a.reference_label, reference_files=a.reference, ours_run=a.ours,
                  built=datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
                  commit=prov.get("commit"), dirty=prov.get("dirty"))
    os.makedirs(a.out, exist_ok=True)
    write_json_atomic(os.path.join(a.out, f"{a.name}.json"), json_numbers(result))
    figure(a.name, result, os.path.join(a.out, f"{a.name}.png"))
    write_text_atomic(os.path.join(a.out, f"{a.name}.md"), markdown(a.name, result))
    print(f"{a.name}: ours {fmt(result['ours']['mean'])}, {a.reference_label} {fmt(result['reference']['mean'])}: "
          f"{result['verdict']}; wrote {os.path.join(a.out, a.name)}.md/.json/.png")
    return 0
