"""Export the deterministic actors of a run (from any checkpoint) for use outside training code.

    python -m experiments.export runs/pendulum-meta-paper-s0                 # latest checkpoint
    python -m experiments.export runs/pendulum-meta-paper-s0 --chunk 10 --out policy_10.npz

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
    args = p.parse_args(argv)
    path = os.path.join(args.run_dir, "config.json")
    if not os.path.exists(path):
        print(f"error: {args.run_dir} has no config.json (not a run folder)", file=sys.stderr)
        return 2

    import jax

    from metapg_jax import config as config_lib
    from metapg_jax.checkpoint import Checkpointer, saved_steps
    from metapg_jax.policy import export_policies
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
    return 0


if __name__ == "__main__":
    sys.exit(main())
