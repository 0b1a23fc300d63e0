"""The terminal's view of a long run: a progress bar over env steps, a duration as a person reads it, and the
process's peak memory."""

from __future__ import annotations

import sys
import time

import numpy as np


class Progress:
    """A tqdm bar over env steps with steps/s, ETA and the latest mean evaluation return.

    ``initial``: env steps per seed already done before this call (a resume or an extension); the bar
    starts there, and both rates (tqdm's per-seed steps/s and the total steps/s) count only the steps
    trained in this call."""

    def __init__(self, total_steps: int, num_seeds: int, desc: str, disable: bool | None = None,
                 initial: int = 0):
        from tqdm import tqdm

        self.num_seeds = num_seeds
        self.initial = self.steps = initial  # env steps per seed: before this call, and so far
        self.start = time.perf_counter()
        self.bar = tqdm(total=total_steps, initial=initial, desc=desc, unit="step", dynamic_ncols=True,
                        disable=disable if disable is not None else False, file=sys.stderr,
                        bar_format="{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}<{remaining}, {rate_fmt}{postfix}]")

    def total_rate(self) -> float:
        """Env steps per second over all seeds, trained in this call."""
        return self.num_seeds * (self.steps - self.initial) / max(time.perf_counter() - self.start, 1e-9)

    def update(self, env_steps: int, eval_returns: np.ndarray) -> None:
        self.bar.update(env_steps - self.steps)
        self.steps = env_steps
        self.bar.set_postfix_str(
            f"eval {np.mean(eval_returns):.1f} ± {np.std(eval_returns):.1f} | {self.total_rate():,.0f} total steps/s")

    def close(self) -> None:
        self.bar.close()


def duration(seconds: float) -> str:
    """'42 s', '12.5 min' or '3.20 h'."""
    if seconds < 120:
        return f"{seconds:,.0f} s"
    return f"{seconds / 60:,.1f} min" if seconds < 7200 else f"{seconds / 3600:,.2f} h"


def peak_rss_mib() -> float:
    """This process's peak resident memory in MiB (Linux reports ``ru_maxrss`` in KiB)."""
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
