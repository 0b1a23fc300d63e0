"""Export and load trained deterministic policies, outside JAX training code.

``export_policies(path, config, student_actor, normalizer)`` writes one
self-describing ``.npz`` file holding, for every seed, the actor's parameters
and the observation normaliser, plus a JSON description (architecture, task,
action scaling, config). ``load_policy(path, seed=i)`` returns a plain
function ``numpy obs (obs_size,) or (batch, obs_size) -> numpy action in
[-1, 1]^action_size`` computed with NumPy alone (no JAX needed at load time).
The description's ``output`` says how the last layer gives the action (``OUTPUTS``).

Actions are in the normalised box [-1, 1] every task of this project uses;
``description["action_low"/"action_high"]`` give the env's own bounds
(``low + (a + 1) / 2 * (high - low)``) for use with e.g. gymnasium directly.
"""

from __future__ import annotations

import json
from typing import Callable

import numpy as np

FORMAT = "metapg-jax-policy/1"
# The acting policies the NumPy loader computes (a student declares its own: metapg_jax.strategy, architecture).
KINDS = ("mlp",)
# What the MLP's last layer holds, as columns per action: "tanh", the action is tanh of its output; "tanh-mean",
# it has 2 * action_size columns (a mean and another statistic per action) and the action is tanh of the first
# action_size, the mean (a squashed-Gaussian policy's deterministic action).
OUTPUTS = {"tanh": 1, "tanh-mean": 2}


def _flatten(tree, prefix=""):
    out = {}
    for k, v in tree.items():
        name = f"{prefix}/{k}" if prefix else k
        if isinstance(v, dict):
            out.update(_flatten(v, name))
        else:
            out[name] = np.asarray(v)
    return out


def export_policies(path: str, config, student_actor, normalizer, action_low=None, action_high=None) -> None:
    """Writes the actors of all seeds (leading seed axis) and their normalisers to ``path`` atomically."""
    from metapg_jax import config as config_lib
    from metapg_jax import normalizer as norm_lib
    from metapg_jax import strategy
    from metapg_jax.actor_critic import actor_architecture

    describe_actor = strategy.student(config.student).architecture or actor_architecture
    architecture = describe_actor(config)
    if architecture.get("kind") not in KINDS:
        raise ValueError(f"policy.npz cannot describe a {architecture.get('kind')!r} policy (student "
                         f"{config.student!r}); the NumPy loader knows: {', '.join(KINDS)}")
    output = architecture.get("output", "tanh")
    if output not in OUTPUTS:
        raise ValueError(f"policy.npz cannot describe an MLP with output {output!r} (student {config.student!r}); "
                         f"the NumPy loader knows: {', '.join(OUTPUTS)}")
    actor = _flatten(student_actor["params"] if "params" in student_actor else student_actor)
    mean, std = norm_lib.mean_std(normalizer)
    num_seeds = int(np.asarray(mean).shape[0])
    description = {
        "format": FORMAT,
        "num_seeds": num_seeds,
        "env": config.env.name,
        "source": config.env.source,
        **architecture,
        "obs_size": int(np.asarray(mean).shape[-1]),
        "action_size": int(actor["out/bias"].shape[-1]) // OUTPUTS[output],
        "action_low": None if action_low is None else np.asarray(action_low).tolist(),
        "action_high": None if action_high is None else np.asarray(action_high).tolist(),
        "config": config_lib.to_dict(config),
    }
    arrays = {f"actor/{k}": v for k, v in actor.items()}
    arrays["normalizer/mean"] = np.asarray(mean)
    arrays["normalizer/std"] = np.asarray(std)
    arrays["description"] = np.frombuffer(json.dumps(description).encode(), dtype=np.uint8)
    from metapg_jax.host.runfiles import savez_atomic

    savez_atomic(path, arrays)


def describe(path: str) -> dict:
    with np.load(path) as f:
        return json.loads(bytes(f["description"]).decode())


def load_policy(path: str, seed: int = 0) -> Callable[[np.ndarray], np.ndarray]:
    """A NumPy function obs -> action for seed ``seed`` of an exported file."""
    with np.load(path) as f:
        desc = json.loads(bytes(f["description"]).decode())
        if desc.get("format") != FORMAT:
            raise ValueError(f"{path} is not a {FORMAT} file")
        if desc.get("kind", "mlp") not in KINDS:  # (files written before "kind" existed hold MLPs)
            raise ValueError(f"{path} holds a {desc['kind']!r} policy; this loader computes: {', '.join(KINDS)}")
        output = desc.get("output", "tanh")  # (files written before "output" existed end in tanh)
        if output not in OUTPUTS:
            raise ValueError(f"{path} holds an MLP with output {output!r}; this loader computes: {', '.join(OUTPUTS)}")
        if not 0 <= seed < desc["num_seeds"]:
            raise ValueError(f"seed {seed} out of range: {path} holds {desc['num_seeds']} seeds")
        p = {k[len("actor/"):]: f[k][seed].astype(np.float64) for k in f.files if k.startswith("actor/")}
        mean = f["normalizer/mean"][seed].astype(np.float64)
        std = f["normalizer/std"][seed].astype(np.float64)
    n_hidden, ln, eps, clip = len(desc["hidden"]), desc["layer_norm"], desc["layer_norm_epsilon"], desc["obs_clip"]
    normalize, action_size = desc["normalize_obs"], desc["action_size"]

    def policy(obs: np.ndarray) -> np.ndarray:
        x = np.asarray(obs, np.float64)
        if normalize:
            x = np.clip((x - mean) / std, -clip, clip)
        for i in range(n_hidden):
            x = x @ p[f"dense_{i}/kernel"] + p[f"dense_{i}/bias"]
            if ln:
                mu = x.mean(-1, keepdims=True)
                var = x.var(-1, keepdims=True)
                x = (x - mu) / np.sqrt(var + eps) * p[f"ln_{i}/scale"] + p[f"ln_{i}/bias"]
            x = np.maximum(x, 0.0)
        out = x @ p["out/kernel"] + p["out/bias"]
        return np.tanh(out[..., :action_size]).astype(np.float32)  # "tanh-mean": the first action_size columns

    policy.description = desc  # type: ignore[attr-defined]
    return policy
