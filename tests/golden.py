"""Reference numbers of short runs of every method, for checking that a refactoring changes nothing.

``tests/golden_numbers.json`` holds, per case, the evaluation returns of a tiny two-seed run of two
chunks and a hash of the final student parameters, as the code computed them when the file was
written (with the machine it was written on). ``tests/test_golden.py`` recomputes them. Rewrite the
file only for a change that is meant to change the numbers, and say so in the commit:

    python -m tests.golden --write
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
import platform
import sys

import jax
import numpy as np

from metapg_jax.config import make_config
from metapg_jax.host import provenance
from metapg_jax.train import make_train, seed_keys, vmap_seeds
from tests.helpers import tiny_config

PATH = os.path.join(os.path.dirname(os.path.abspath(__file__)), "golden_numbers.json")

# name -> (env, method, preset, noise, teacher, physics[, student])
CASES = {
    "pendulum-ddpg-adaptive-param": ("pendulum", "ddpg", "paper", "adaptive-param", None, "mjx"),
    "pendulum-ddpg-normal": ("pendulum", "ddpg", "paper", "normal", None, "mjx"),
    "pendulum-ddpg-ou": ("pendulum", "ddpg", "paper", "ou", None, "mjx"),
    "pendulum-ddpg-none": ("pendulum", "ddpg", "paper", "none", None, "mjx"),
    "pendulum-meta-independent": ("pendulum", "meta", "paper", None, "independent", "mjx"),
    "pendulum-meta-variance": ("pendulum", "meta", "paper", None, "variance", "mjx"),
    "pendulum-ddpg-modern": ("pendulum", "ddpg", "modern", None, None, "mjx"),
    "pendulum-meta-modern": ("pendulum", "meta", "modern", None, None, "mjx"),
    "idp-ddpg-adaptive-param-mujoco": ("inverted_double_pendulum", "ddpg", "paper", "adaptive-param", None, "mujoco"),
    "idp-meta-independent-mujoco": ("inverted_double_pendulum", "meta", "paper", None, "independent", "mujoco"),
    "pendulum-ddpg-normal-td3": ("pendulum", "ddpg", "paper", "normal", None, "mjx", "td3"),
    "pendulum-meta-independent-td3": ("pendulum", "meta", "paper", None, "independent", "mjx", "td3"),
    "pendulum-ddpg-pink": ("pendulum", "ddpg", "paper", "pink", None, "mjx"),
    "pendulum-ddpg-mixed": ("pendulum", "ddpg", "paper", "mixed", None, "mjx"),
    "pendulum-own-pink-sac": ("pendulum", "own", "paper", "pink", None, "mjx", "sac"),
    "pendulum-meta-independent-sac": ("pendulum", "meta", "paper", None, "independent", "mjx", "sac"),
    "pendulum-meta-residual": ("pendulum", "meta", "paper", None, "residual", "mjx"),
    "pendulum-meta-bandit": ("pendulum", "meta", "paper", None, "bandit", "mjx"),
    "pendulum-meta-uniform": ("pendulum", "meta", "paper", None, "uniform", "mjx"),
    "pendulum-random-td3": ("pendulum", "random", "paper", None, None, "mjx", "td3"),
}


def case_config(name: str):
    env, method, preset, noise, teacher, physics, *student = CASES[name]
    if preset == "paper":
        overrides = {"noise.kind": noise} if noise else {}
        if teacher:
            overrides["meta.teacher"] = teacher
        cfg = tiny_config(method, env=env, physics=physics, **overrides)
        return dataclasses.replace(cfg, student=student[0]) if student else cfg
    return make_config(env, method, "modern", steps=600, physics=physics, overrides={
        "run.eval_every": 300, "run.eval_episodes": 2, "ddpg.hidden": "16,16", "meta.hidden": "16,16",
        "ddpg.batch_size": 16, "run.warmup_steps": 100, "meta.visit_samples": 64, "env.episode_length": 60,
        **({"meta.explore_steps": 50, "meta.eval_steps": 100} if method == "meta" else {})})


# The seeds of every case (seed_keys(*KEYS)).
KEYS = (7, 2)


def compute(name: str) -> dict:
    """Evaluation returns per chunk (seeds x episodes) and a hash of the final student parameters."""
    return numbers(*run_chunks(make_train(case_config(name))))


def run_chunks(trainer, init=None, chunk=None):
    """A case's chunks from ``seed_keys(*KEYS)``: (final state, each chunk's metrics). ``init`` and ``chunk``:
    the jitted, seed-vmapped ``trainer.init`` and ``trainer.train_chunk`` of a test that runs them again
    (default: jitted here)."""
    init = init or jax.jit(vmap_seeds(trainer.init))
    chunk = chunk or jax.jit(vmap_seeds(trainer.train_chunk))
    state, metrics = init(seed_keys(*KEYS)), []
    for _ in range(trainer.config.num_chunks):
        state, m = chunk(state)
        metrics.append(m)
    return state, metrics


def numbers(state, metrics) -> dict:
    """A case's numbers from ``run_chunks``'s final state and chunk metrics."""
    leaves = jax.tree.leaves(jax.device_get(state.student))
    digest = hashlib.sha256(b"".join(np.ascontiguousarray(x).tobytes() for x in leaves)).hexdigest()
    return {"eval_return": [np.asarray(m["eval_return"]).tolist() for m in metrics], "student_sha256": digest}


@functools.lru_cache(maxsize=None)
def stored() -> dict:
    """``golden_numbers.json`` as written."""
    with open(PATH) as f:
        return json.load(f)


def assert_stored(name: str, got: dict) -> None:
    """``got`` (``numbers``) equals the stored numbers of case ``name``: bit for bit, parameters included,
    on a machine like the one that wrote the file (same CPU and JAX version), else the returns to a
    tolerance (XLA may round float32 differently elsewhere)."""
    want = stored()["cases"][name]
    if stored()["machine"] == machine():
        assert got["eval_return"] == want["eval_return"], name
        assert got["student_sha256"] == want["student_sha256"], name
    else:
        np.testing.assert_allclose(got["eval_return"], want["eval_return"], rtol=1e-3, atol=1e-3, err_msg=name)


def machine() -> dict:
    """What decides whether float32 results can be equal bit for bit: the CPU and the JAX version."""
    return {"cpu": provenance.cpu_fingerprint(), "processor": platform.machine(), "jax": jax.__version__,
            "backend": jax.default_backend()}


def main(argv: list[str]) -> int:
    if argv != ["--write"]:
        print(__doc__, file=sys.stderr)
        return 2
    numbers = {"machine": machine(), "cases": {name: compute(name) for name in CASES}}
    with open(PATH, "w") as f:
        json.dump(numbers, f, indent=1)
        f.write("\n")
    print(f"wrote {PATH}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
