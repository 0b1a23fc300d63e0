"""The two physics engines side by side (MJX vs MuJoCo's C engine) from the training rows: the table
appended to the training section of ``BENCHMARKS.md`` and the targets it states."""

from __future__ import annotations

from experiments.benchmarks.records import _date

ENGINE_TARGETS = {"speedup": 4.0, "speedup_tasks": ("hopper", "halfcheetah"), "updates_share": 0.85,
                  "c_compile_s": 30.0}


def engines_markdown(rows: list[dict]) -> list[str]:
    """The two engines side by side, from rows measured on the same date: training throughput with
    MuJoCo's C engine over MJX's; for the C rows, the share of full training time that the DDPG updates
    alone take (1 = physics and bookkeeping cost nothing on top of the updates) and the cold compile."""
    import envs  # brax on import: only when the table is written

    key = lambda r: (r["env"], r["method"], r["preset"], r["seeds"], _date(r))
    mjx = {key(r): r for r in rows if r.get("physics", "mjx") == "mjx" and not r.get("stock_mjx")
           and not r.get("plain_vmap") and envs.has_mujoco(r["env"])}
    c_rows = [r for r in rows if r.get("physics") == "mujoco"]
    if not c_rows:
        return []
    t = ENGINE_TARGETS
    out = ["", f"Engines side by side (rows of the same date): C engine total steps/s over MJX's (target >= "
           f"{t['speedup']:.0f}x on {' and '.join(t['speedup_tasks'])} at 8 seeds, paper preset); updates share "
           f"= updates-alone time / full training time (target >= {t['updates_share']} for the modern preset at 1 "
           f"seed on Hopper); the C engine's cold compile (target <= {t['c_compile_s']:.0f} s).", "",
           "| task | method | preset | seeds | measured | MJX steps/s | C steps/s | C / MJX | updates share | "
           "compile s, MJX / C |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in sorted(c_rows, key=lambda r: (r["env"], r["preset"], r["method"], r["seeds"])):
        m = mjx.get(key(r))
        ratio = f"{r['steps_per_s_total'] / m['steps_per_s_total']:.2f}x" if m else "–"
        out.append(f"| {r['env']} | {r['method']} | {r['preset']} | {r['seeds']} | {_date(r)} | "
                   f"{m and format(m['steps_per_s_total'], ',.0f') or '–'} | {r['steps_per_s_total']:,.0f} | {ratio} | "
                   f"{r['updates_s'] / r['full_s']:.2f} | {m and format(m['compile_s'], '.1f') or '–'} / "
                   f"{r['compile_s']:.1f} |")
    return out

