"""What ``experiments.strength.cleanrl`` writes into CleanRL's venv and runs there (with that venv's Python, so
never imported here): our env ids, the checks of the venv, and the reader of CleanRL's TensorBoard events. Our
code, not CleanRL's.

``SITECUSTOMIZE`` and ``ENVS`` are the venv's ``strength-site/sitecustomize.py`` and ``strength_envs.py``: the
first registers ``compat/Hopper-v5`` and ``dmc-flat/<domain>-<task>-v0`` when the venv's Python starts with that
folder on PYTHONPATH, the second builds them when gymnasium makes one. ``TRACE``, ``CHECK`` and ``EXTRACT`` are
``python -c`` programs that print one JSON line.
"""

SITECUSTOMIZE = '''"""Registers the env ids of metapg-jax's experiments/strength (our code, not CleanRL's)."""
import os

# This folder leaves PYTHONPATH before gymnasium is imported: importing dm_control (shimmy's registrations) starts a
# Python subprocess (glfw's library probe) that would run this file again, and that one another, without end.
_here = os.path.dirname(os.path.abspath(__file__))
os.environ["PYTHONPATH"] = os.pathsep.join(p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep)
                                           if p and os.path.abspath(p) != _here)
import gymnasium  # noqa: E402

gymnasium.register("compat/Hopper-v5", entry_point="strength_envs:HopperV5", max_episode_steps=1000)
for _id in [i for i in gymnasium.registry if i.startswith("dm_control/")]:
    gymnasium.register("dmc-flat/" + _id[len("dm_control/"):], entry_point="strength_envs:dmc_flat",
                       kwargs={"dm_id": _id})
'''
ENVS = '''"""The env ids' constructors (metapg-jax's experiments/strength/cleanrl.py; our code, not CleanRL's)."""
import gymnasium
from gymnasium.envs.mujoco.hopper_v4 import HopperEnv


class HopperV5(HopperEnv):
    """Hopper-v4 with v5's healthy reward: paid only while healthy (gymnasium 1.0's fix), as v5 computes it."""

    @property
    def healthy_reward(self):
        return self.is_healthy * self._healthy_reward


def dmc_flat(dm_id, **kwargs):
    """shimmy's dm_control env with its dict of observations flattened into one vector."""
    return gymnasium.wrappers.FlattenObservation(gymnasium.make(dm_id, **kwargs))
'''
# Run with both interpreters: gymnasium's Hopper-v5 (project venv) and compat/Hopper-v5 (CleanRL's venv).
TRACE = '''import json, sys
import gymnasium as gym, numpy as np
env, rng = gym.make(sys.argv[1]), np.random.default_rng(0)
env.reset(seed=0)
rows = []
for _ in range(int(sys.argv[2])):
    obs, r, term, trunc, _ = env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
    rows.append([float(r), bool(term), bool(trunc), [float(x) for x in obs]])
    if term or trunc:
        env.reset()
print(json.dumps(rows))
'''
CHECK = '''import json, gymnasium as gym, torch, jax, flax, tyro
shapes = {i: gym.make(i).reset(seed=0)[0].shape for i in ("compat/Hopper-v5", "dmc-flat/walker-walk-v0")}
print(json.dumps({"obs_shapes": {i: list(s) for i, s in shapes.items()}, "torch_cuda": torch.cuda.is_available(),
                  "jax_backend": jax.default_backend()}))
'''
EXTRACT = '''import json, sys
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator
acc = EventAccumulator(sys.argv[1], size_guidance={"scalars": 0})  # 0: keep every point, not a sample
acc.Reload()
tag = sys.argv[2]
print(json.dumps([[e.step, e.value] for e in acc.Scalars(tag)] if tag in acc.Tags()["scalars"] else []))
'''
