"""Export the deterministic actors of a run (from any checkpoint) for use outside training code.

    python -m experiments.export runs/pendulum-meta-paper-s0                 # latest checkpoint
    python -m experiments.export runs/pendulum-meta-paper-s0 --chunk 10 --out policy_10.npz

    python -m experiments.export RUN --replay 10 --report replay.json   # and replay them in the task's own env

``--replay N`` runs each seed's exported policy for N episodes in the task's own reference environment
(gymnasium's, with a ``gym:`` task's keyword arguments; for a ``dmc:`` task dm_control's suite, its observation
dict flattened in key order as in training), on MuJoCo's C engine, episode seeds 0..N-1, actions mapped from
[-1, 1] to the env's bounds, and sets the mean return beside the run's last in-training evaluation
(``metrics.jsonl``); ``--report`` stores both as JSON with the run's provenance and the command.

Then, anywhere (NumPy only)::

    from metapg_jax import load_policy
    act = load_policy("runs/pendulum-meta-paper-s0/policy.npz", seed=0)
    action = act(obs)          # obs: numpy (obs_size,) -> action in [-1, 1]^action_size
"""

from __future__ import annotations

import argparse
import json
import os
import sys


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.export", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("run_dir", help="a run folder written by experiments.run")
    p.add_argument("--chunk", type=int, default=None, help="checkpoint to export (chunks done); default the latest")
    p.add_argument("--out", default=None, help="output file (default RUN_DIR/policy.npz, or policy_<chunk>.npz)")
    p.add_argument("--replay", type=int, default=0, metavar="N",
                   help="replay each seed's exported policy for N episodes in the task's reference environment "
                        "(gymnasium's; dm_control's suite for a dmc: task)")
    p.add_argument("--report", default=None, help="with --replay: write the replay's returns to this JSON file")
    args = p.parse_args(argv)
    if args.replay < 0 or (args.report and not args.replay):
        print("error: --replay takes a positive number of episodes" if args.replay < 0 else
              "error: --report needs --replay N", file=sys.stderr)
        return 2
    path = os.path.join(args.run_dir, "config.json")
    if not os.path.exists(path):
        print(f"error: {args.run_dir} has no config.json (not a run folder)", file=sys.stderr)
        return 2

    import jax

    from metapg_jax import config as config_lib
    from metapg_jax.host.checkpoint import Checkpointer, saved_steps
    from metapg_jax.host.policy import export_policies
    from metapg_jax.loop import checkpoint_shapes
    from metapg_jax.train import make_train, seed_keys

    steps = saved_steps(os.path.join(args.run_dir, "checkpoints"))
    if not steps or (args.chunk is not None and args.chunk not in steps):
        have = ", ".join(map(str, steps)) or "none"
        print(f"error: {args.run_dir}: no checkpoint" + (f" after {args.chunk} chunks" if steps else "") +
              f" (checkpoints there, by chunks done: {have})", file=sys.stderr)
        return 2
    out = args.out or os.path.join(args.run_dir, "policy.npz" if args.chunk is None else f"policy_{args.chunk}.npz")
    if os.path.isdir(out) or not os.path.isdir(os.path.dirname(os.path.abspath(out))):
        print(f"error: --out {out}: " + ("is a folder; name a file" if os.path.isdir(out) else
                                         "its folder does not exist"), file=sys.stderr)
        return 2
    try:  # a hand-edited or truncated config.json: one line, not a traceback from deep inside the build
        with open(path) as f:
            stored = json.load(f)
        from experiments.training.args import import_plugins

        import_plugins(stored.get("run_args", {}).get("plugins") or [])  # a plug-in's strategy and group
        cfg = config_lib.validate(config_lib.from_dict(stored["config"]))
        a = {"seed": int(stored["run_args"]["seed"]), "seeds": int(stored["run_args"]["seeds"])}
    except (OSError, ValueError, KeyError, TypeError) as err:
        print(f"error: {path} is not a usable run config ({type(err).__name__}: {err})", file=sys.stderr)
        return 2
    trainer = make_train(cfg)
    ckpt = Checkpointer(os.path.join(args.run_dir, "checkpoints"))
    try:
        state, meta = ckpt.restore(checkpoint_shapes(trainer, seed_keys(a["seed"], a["seeds"])), step=args.chunk)
    except FileNotFoundError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    finally:
        ckpt.close()
    export_policies(out, cfg, jax.device_get(state.student.actor), jax.device_get(state.normalizer))
    print(f"exported {a['seeds']} policies after {meta['chunks_done']} chunks "
          f"({meta['chunks_done'] * cfg.run.eval_every:,} env steps) to {out}")
    if args.replay:
        report = replay_report(out, cfg, args.run_dir, meta["chunks_done"], args.replay,
                               ["python", "-m", "experiments.export", *(sys.argv[1:] if argv is None else argv)])
        for seed in report["seeds"]:
            print(f"seed {seed['seed']}: {report['reference']} {seed['replay_mean']:,.1f} over {args.replay} episodes, "
                  f"in-training evaluation {seed['training_eval']:,.1f}")
        if args.report:
            from metapg_jax.host.runfiles import write_json_atomic

            write_json_atomic(args.report, report)
            print(f"wrote {args.report}")
    return 0


def replay_in_gymnasium(policy_path: str, gym_id: str, seed: int, episodes: int, **kwargs) -> list[float]:
    """The returns of ``episodes`` episodes of seed ``seed``'s exported policy in ``gymnasium.make(gym_id,
    **kwargs)`` (episode i reset with seed i; the policy's [-1, 1] actions mapped to the env's action bounds)."""
    import gymnasium
    import numpy as np

    from envs.mujoco_base import without_the_settotalmass_warning
    from metapg_jax.host.policy import load_policy

    act = load_policy(policy_path, seed=seed)
    with without_the_settotalmass_warning():
        env = gymnasium.make(gym_id, **kwargs)
    low, high = env.action_space.low.astype(np.float64), env.action_space.high.astype(np.float64)
    returns = []
    try:
        for episode in range(episodes):
            obs, _ = env.reset(seed=episode)
            total, done = 0.0, False
            while not done:
                action = low + (np.asarray(act(obs), np.float64) + 1.0) * 0.5 * (high - low)
                obs, reward, terminated, truncated, _ = env.step(action.astype(env.action_space.dtype))
                total += float(reward)
                done = terminated or truncated
            returns.append(total)
    finally:
        env.close()
    return returns


def replay_in_dm_control(policy_path: str, name: str, seed: int, episodes: int) -> list[float]:
    """The returns of ``episodes`` episodes of seed ``seed``'s exported policy in dm_control's suite task ``name``
    (``dmc:<domain>-<task>``; episode i loaded with ``task_kwargs={"random": i}``; the observation dict flattened
    in key order and cast to float32, as the ``dmc:`` tasks give it; actions mapped to the action spec's bounds)."""
    import numpy as np
    from dm_control import suite

    from envs import dmc_names
    from metapg_jax.host.policy import load_policy

    act = load_policy(policy_path, seed=seed)
    domain, task = dmc_names.parse_name(name)
    returns = []
    for episode in range(episodes):
        env = suite.load(domain, task, task_kwargs={"random": episode})
        spec = env.action_spec()
        low, high = spec.minimum.astype(np.float64), spec.maximum.astype(np.float64)
        step, total = env.reset(), 0.0
        while not step.last():
            obs = np.concatenate([np.asarray(v, np.float64).ravel() for v in step.observation.values()])
            step = env.step(low + (np.asarray(act(obs.astype(np.float32)), np.float64) + 1.0) * 0.5 * (high - low))
            total += float(step.reward)
        returns.append(total)
    return returns


def replay_report(policy_path: str, cfg, run_dir: str, chunks_done: int, episodes: int, command: list[str]) -> dict:
    """Per seed: the replay's returns (``replay_in_gymnasium``, or ``replay_in_dm_control`` for a ``dmc:`` task)
    beside the run's in-training evaluation after the same chunk, with the provenance of the run and of the replay."""
    import datetime

    import numpy as np

    from envs import get_spec, is_dmc_task, is_gym_task
    from metapg_jax.host import provenance, runfiles

    name = cfg.env.name
    if is_dmc_task(name):
        envs_of = {"reference": "dm_control", "dm_control": name}
        replay = lambda seed: replay_in_dm_control(policy_path, name, seed, episodes)
    else:
        from envs.gym_names import parse_name

        gym_id, kwargs = get_spec(name).gym_id, dict(parse_name(name)[1]) if is_gym_task(name) else {}
        envs_of = {"reference": "gymnasium", "gym_id": gym_id, "gym_kwargs": kwargs}
        replay = lambda seed: replay_in_gymnasium(policy_path, gym_id, seed, episodes, **kwargs)
    rows = [r for r in runfiles.read_jsonl(os.path.join(run_dir, "metrics.jsonl")) if r["chunk"] == chunks_done - 1]
    training = {int(r["seed"]): float(r["eval_return"]) for r in rows}
    with open(os.path.join(run_dir, "config.json")) as f:
        stored = json.load(f)
    seeds = []
    for seed in sorted(training):
        returns = replay(seed)
        seeds.append({"seed": seed, "replay_returns": returns, "replay_mean": float(np.mean(returns)),
                      "training_eval": training[seed],
                      "relative_difference": (float((np.mean(returns) - training[seed]) / abs(training[seed]))
                                              if training[seed] else None)})  # a sparse task's 0: none
    return {**envs_of, "episodes": episodes, "chunks_done": chunks_done, "command": command,
            "run": {k: stored.get(k) for k in ("run_args", "commit", "dirty")} | {"physics": cfg.env.physics},
            "training_eval_episodes": cfg.run.eval_episodes,
            "replayed": {"date": datetime.date.today().isoformat(), **provenance.record()}, "seeds": seeds}


if __name__ == "__main__":
    sys.exit(main())
