"""CleanRL's TD3 and SAC, unchanged, on our tasks: the reference side of the strength comparison, run by hand, never
in CI. CleanRL's code stays outside the repository; this script and the numbers are committed.

    python -m experiments.strength.cleanrl setup --venv ~/cleanrl-venv --cleanrl A-CLONE-OF-vwxyzjn/cleanrl
    python -m experiments.strength.cleanrl run --venv ~/cleanrl-venv --algo td3 --task hopper --seeds 1,2,3 \\
        --steps 300000 --out results/measurements/strength-cleanrl-fe8d8a0

``setup`` makes a Python 3.12 venv (``PINS``), copies CleanRL's two files and the replay buffer they import at
``COMMIT`` into it (refusing a file whose sha256 is not ``SHA256``'s), writes our env ids there (a
``sitecustomize`` on PYTHONPATH, so CleanRL's files stay byte-identical) and checks ``compat/Hopper-v5`` against
gymnasium's own Hopper-v5 step by step. ``run`` runs the file once per seed, in turn, given ``--env-id``, ``--seed``
and ``--total-timesteps`` only, each in a folder of its own under ``--runs`` (default the venv's ``runs/``), and
writes its ``charts/episodic_return`` as ``<out>/cleanrl-<algo>-<task>-seed<k>.csv`` and its record (command,
commit, sha256s, packages, machine, wall and CPU time) into ``<out>/run.json``. Exit status: 0 done, 1 a run or
check failed, 2 bad input (one ``error:`` line).

Env ids. CleanRL's files need gymnasium 0.29 (the pre-1.0 vector API: ``infos["final_info"]``,
``infos["final_observation"]``), which has no Hopper-v5: ``compat/Hopper-v5`` is its Hopper-v4 with v5's one change
of the MDP (the healthy reward is paid only while healthy; v4 pays it on the terminating step too; XML,
observation, reset and termination are the same), and ``setup`` fails unless it steps as gymnasium 1.x's Hopper-v5
on random actions through many terminations. ``dmc-flat/<domain>-<task>-v0`` is shimmy's
``dm_control/<domain>-<task>-v0`` under gymnasium's ``FlattenObservation``.

The DMC task is ``dmc:walker-walk``: dense reward, learnt by state-based SAC to ~900 in 300-500k steps in published
curves, so both sides are mid-climb at 300k, where a weaker implementation shows (cartpole-swingup saturates near
850 by ~100k and would hide one; cheetah-run is still low at 300k); contacts and a 6-d action, like Hopper.

Our side: 3 seeds, 300k steps, on the C engine; TD3 explores with the modern preset's Gaussian 0.1, SAC samples its
own policy; then ``--preset=paper`` (TD3 with ``--noise=normal --set noise.stddev=0.1``, the benchmark's cells):

    python -m experiments.run --env=hopper --student=td3 --method=ddpg --preset=modern --seeds=3 --seed=1 \\
        --steps=300000 --physics=mujoco --no-plot --out <folder>/ours-modern-td3-hopper
    ... --student=sac --method=own ...; ... --env=dmc:walker-walk ...

The modern preset against CleanRL's defaults. Equal: 256-256 ReLU networks, action at the critic's input, batch
256, gamma 0.99, tau 0.005, one update per env step, no observation normalisation, all 300k steps kept, only
terminations cut the bootstrap; TD3's Adam 3e-4, policy noise 0.2 clipped at 0.5, actor and targets every 2nd
update, exploration N(0, 0.1), 25k random steps; SAC's actor Adam 3e-4, 5k random steps, alpha from 1 with target
entropy -|A|, log-std squashed into [-5, 2]. Different:
* initialisation: CleanRL's TD3 has flax's LeCun-normal kernels (last layers too), its SAC torch's U(+-1/sqrt(fan
  in)) weights and biases; ours Glorot-uniform hidden kernels, U(+-3e-3) last layers;
* SAC's critic and temperature learning rates: CleanRL's 1e-3 (``q_lr``), ours 3e-4 (``ddpg.critic_lr``,
  ``sac.alpha_lr``); a SAC gap is first rerun with ``--set ddpg.critic_lr=1e-3 --set sac.alpha_lr=1e-3``;
* SAC's schedule: CleanRL steps actor and temperature twice every 2nd update (each on a fresh sample), ours once
  per update; its log-prob takes log(1 - tanh^2 + 1e-6), ours the exact value;
* the first update after 25,001 (TD3) or 5,001 (SAC) stored steps in CleanRL, after 25,000 or 5,000 in ours.

What is compared (``python -m experiments.analysis.strength``, which states the rule). CleanRL logs each training
episode's return (TD3 with its exploration noise, SAC sampling its policy) at the step it ended; ours evaluates the
deterministic policy and records ``train_return``, the mean return of the exploring episodes that ended in each
chunk. Like is compared with like: CleanRL's episodes binned into our chunks against ``train_return``. The
``final_return`` this script stores in ``run.json`` is a quick summary of one run (the mean of its episodes that
ended in the last ``FINAL_FRACTION`` of the steps), not the comparison's.
"""

from __future__ import annotations

import argparse
import datetime
import glob
import hashlib
import json
import os
import platform
import resource
import subprocess
import sys
import time
from typing import NamedTuple

from experiments.strength import cleanrl_venv as venv_code
from metapg_jax.host.runfiles import write_text_atomic

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
COMMIT = "fe8d8a03c41a7ef5b523e2e354bd01c363e786bb"  # vwxyzjn/cleanrl, 2026-04-20
SCRIPTS = {"td3": "cleanrl/td3_continuous_action_jax.py", "sac": "cleanrl/sac_continuous_action.py"}
SHA256 = {
    "cleanrl/td3_continuous_action_jax.py": "e815c2e147c40d331e3dba121eca3d732ba903f5ab1f963ff7d629ddb6d18a50",
    "cleanrl/sac_continuous_action.py": "f411ff829c864f1312dbca6a01b7a8c8830a4d9640e37beffa41630ff71bb7e0",
    "cleanrl_utils/__init__.py": "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855",
    "cleanrl_utils/buffers.py": "b43d54020783ac53f7d23fe7c0ed72aff20e1f377a633d134d66eb9bdbece4b8",
}
PYTHON = (3, 12)
# CleanRL's own pins where they install on Python 3.12 (gymnasium, torch, tyro); its jax 0.4.8 / flax 0.6.8 /
# optax 0.1.4 have no 3.12 wheels, so the last 0.4 jax and the flax and optax of its time; MuJoCo the project's.
PINS = ("gymnasium==0.29.1", "numpy==1.26.4", "torch==2.4.1", "tensorboard==2.21.0", "tyro==0.5.10",
        "jax[cpu]==0.4.30", "jaxlib==0.4.30", "flax==0.8.5", "optax==0.2.3", "chex==0.1.86",
        "mujoco==4.0.1", "dm-control==1.0.52", "shimmy[dm-control]==1.3.0")
VERSIONS = ("gymnasium", "numpy", "torch", "tensorboard", "tyro", "jax", "jaxlib", "flax", "optax", "chex",
            "mujoco", "dm-control", "shimmy")
HOPPER_ID = "compat/Hopper-v5"
TAG = "charts/episodic_return"
FINAL_FRACTION = 0.1

class Refusal(ValueError):
    """Bad input: one line, exit 2."""


class Parser(argparse.ArgumentParser):
    def error(self, message):
        raise Refusal(message)


class Layout(NamedTuple):
    """Where ``setup`` puts things in the venv's folder: CleanRL's tree (``src``: cleanrl/, cleanrl_utils/), our
    env ids (``site``: sitecustomize.py, strength_envs.py) and its record."""
    root: str
    python: str
    src: str
    site: str
    record: str


def layout_of(root: str) -> Layout:
    root = os.path.abspath(root)
    return Layout(root, os.path.join(root, "bin", "python"), os.path.join(root, "cleanrl-src"),
                  os.path.join(root, "strength-site"), os.path.join(root, "strength-setup.json"))


class Run(NamedTuple):
    seed: int
    argv: list[str]
    cwd: str


def env_id(task: str) -> str:
    """Our task name -> the env id CleanRL's file is given: ``hopper`` or ``dmc:<domain>-<task>``."""
    if task == "hopper":
        return HOPPER_ID
    if task.startswith("dmc:"):
        from envs import dmc_names

        try:
            domain, name = dmc_names.parse_name(task)
        except ValueError as err:
            raise Refusal(str(err)) from None
        return f"dmc-flat/{domain}-{name}-v0"
    raise Refusal(f"unknown task {task!r}: hopper or dmc:<domain>-<task> (e.g. dmc:walker-walk)")


def slug(task: str) -> str:
    return task.replace(":", "-")


def parse_seeds(text: str) -> list[int]:
    try:
        seeds = [int(s) for s in text.split(",")]
    except ValueError:
        raise Refusal(f"--seeds takes comma-separated integers, e.g. 1,2,3; got {text!r}") from None
    if min(seeds) < 0 or len(set(seeds)) != len(seeds):
        raise Refusal(f"--seeds must be distinct integers >= 0, got {text!r}")
    return seeds


def inside(path: str, folder: str) -> bool:
    path, folder = os.path.realpath(path), os.path.realpath(folder)
    return os.path.commonpath([path, folder]) == folder


def plan(layout: Layout, algo: str, task: str, seeds: list[int], steps: int, runs: str, stamp: str) -> list[Run]:
    """One run of CleanRL's file per seed: its defaults but for the env id, the seed and the budget."""
    if algo not in SCRIPTS:
        raise Refusal(f"unknown algo {algo!r}: {' or '.join(SCRIPTS)}")
    script = os.path.join(layout.src, SCRIPTS[algo])
    ident = env_id(task)
    return [Run(k, [layout.python, script, "--env-id", ident, "--seed", str(k), "--total-timesteps", str(steps)],
                os.path.join(runs, f"{algo}-{slug(task)}-seed{k}-{stamp}")) for k in seeds]


def child_env(layout: Layout) -> dict[str, str]:
    """Our environment without the project's Python, JAX and XLA settings, with CleanRL's tree and our env ids."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "JAX_", "XLA_"))}
    env["PYTHONPATH"] = os.pathsep.join([layout.src, layout.site])
    return env


def csv_text(points: list[tuple[int, float]]) -> str:
    return "step,episodic_return\n" + "".join(f"{int(s)},{float(v)!r}\n" for s, v in points)


def final_return(points: list[tuple[int, float]], steps: int) -> float | None:
    """Mean return of the episodes that ended in the last ``FINAL_FRACTION`` of the steps (None if none did)."""
    last = [v for s, v in points if s >= (1 - FINAL_FRACTION) * steps]
    return sum(last) / len(last) if last else None


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def read_source(cleanrl: str, path: str) -> bytes:
    """A file at ``COMMIT`` from a clone (bare or not) of CleanRL, else from a plain tree of it."""
    out = subprocess.run(["git", "-C", cleanrl, "show", f"{COMMIT}:{path}"], capture_output=True)
    if out.returncode == 0:
        return out.stdout
    try:
        with open(os.path.join(cleanrl, path), "rb") as f:
            return f.read()
    except OSError:
        raise Refusal(f"{cleanrl} holds neither commit {COMMIT[:7]} of CleanRL nor a file {path}") from None


def write(path: str, data: bytes | str) -> None:
    os.makedirs(os.path.dirname(path), exist_ok=True)
    write_text_atomic(path, data)


def venv_json(layout: Layout, code: str, *args: str) -> object:
    out = subprocess.run([layout.python, "-c", code, *args], env=child_env(layout), capture_output=True, text=True)
    if out.returncode:
        raise RuntimeError(f"{code.splitlines()[0]} ... failed in the venv:\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def packages(layout: Layout) -> dict[str, str]:
    out = subprocess.run([layout.python, "-m", "pip", "freeze", "--all"], capture_output=True, text=True, check=True)
    pairs = [line.split("==", 1) for line in out.stdout.splitlines() if "==" in line]
    return {name.lower().replace("_", "-"): version for name, version in pairs}


def hopper_check(layout: Layout, steps: int = 1000) -> dict:
    """compat/Hopper-v5 (CleanRL's venv) against gymnasium 1.x's Hopper-v5 (ours) on the same random actions."""
    theirs = venv_json(layout, venv_code.TRACE, HOPPER_ID, str(steps))
    out = subprocess.run([sys.executable, "-c", venv_code.TRACE, "Hopper-v5", str(steps)], capture_output=True,
                         text=True, check=True)
    ours = json.loads(out.stdout.strip().splitlines()[-1])
    flags = all(a[1:3] == b[1:3] for a, b in zip(theirs, ours))
    d_reward = max(abs(a[0] - b[0]) for a, b in zip(theirs, ours))
    d_obs = max(abs(x - y) for a, b in zip(theirs, ours) for x, y in zip(a[3], b[3]))
    return {"steps": steps, "terminations": sum(r[1] for r in ours), "flags_equal": flags,
            "max_abs_reward_diff": d_reward, "max_abs_obs_diff": d_obs,
            "equal": flags and d_reward <= 1e-9 and d_obs <= 1e-9}


def setup(args) -> int:
    layout = layout_of(args.venv)
    if inside(layout.root, REPO):
        raise Refusal(f"--venv {args.venv} is inside the repository; CleanRL's code stays outside it")
    cleanrl = args.cleanrl or os.environ.get("CLEANRL_REPO")
    if not cleanrl or not os.path.isdir(cleanrl):
        raise Refusal("setup needs a clone of vwxyzjn/cleanrl: --cleanrl DIR (or $CLEANRL_REPO)")
    sources = {path: read_source(cleanrl, path) for path in SHA256}
    wrong = [p for p, data in sources.items() if sha256(data) != SHA256[p]]
    if wrong:
        raise Refusal(f"{cleanrl}: {wrong[0]} is not the file of CleanRL's commit {COMMIT[:7]} (sha256 differs)")
    python = args.python or sys.executable
    version = subprocess.run([python, "-c", "import sys; print(*sys.version_info[:3])"], capture_output=True,
                             text=True)
    if version.returncode or tuple(int(v) for v in version.stdout.split()[:2]) != PYTHON:
        raise Refusal(f"--python {python} is not Python {PYTHON[0]}.{PYTHON[1]}, which the pins are for")
    if not os.path.exists(layout.python):
        subprocess.run([python, "-m", "venv", layout.root], check=True)
    subprocess.run([layout.python, "-m", "pip", "install", "--upgrade", "pip"], check=True)
    subprocess.run([layout.python, "-m", "pip", "install", *PINS], check=True)
    for path, data in sources.items():
        write(os.path.join(layout.src, path), data)
    write(os.path.join(layout.site, "sitecustomize.py"), venv_code.SITECUSTOMIZE)
    write(os.path.join(layout.site, "strength_envs.py"), venv_code.ENVS)
    check, hopper = venv_json(layout, venv_code.CHECK), hopper_check(layout)
    record = {"cleanrl": {"repository": "vwxyzjn/cleanrl", "commit": COMMIT, "files": SHA256}, "pins": list(PINS),
              "python": version.stdout.split(), "packages": packages(layout), "check": check,
              "hopper_v5_check": hopper, "created": now()}
    write(layout.record, json.dumps(record, indent=1) + "\n")
    print(f"set up {layout.root}: CleanRL {COMMIT[:7]}, {check}; compat/Hopper-v5 vs gymnasium's Hopper-v5 over "
          f"{hopper['steps']} steps ({hopper['terminations']} terminations): max |reward diff| "
          f"{hopper['max_abs_reward_diff']:.3g}, max |obs diff| {hopper['max_abs_obs_diff']:.3g}")
    if not hopper["equal"]:
        print("error: compat/Hopper-v5 differs from gymnasium's Hopper-v5 (see hopper_v5_check)", file=sys.stderr)
        return 1
    return 0


def now() -> str:
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


def machine() -> dict:
    try:
        from metapg_jax.host import provenance

        return provenance.record()
    except Exception as err:  # noqa: BLE001 - the record must not stop a run
        return {"platform": platform.platform(), "python": platform.python_version(), "cpu_count": os.cpu_count(),
                "provenance_error": repr(err)}


def check_setup(layout: Layout) -> dict:
    if not os.path.exists(layout.record) or not os.path.exists(layout.python):
        raise Refusal(f"--venv {layout.root} is not set up: run `python -m experiments.strength.cleanrl setup "
                      f"--venv {layout.root}` first")
    for path, digest in SHA256.items():
        with open(os.path.join(layout.src, path), "rb") as f:
            if sha256(f.read()) != digest:
                raise Refusal(f"{layout.src}/{path} has changed since setup (sha256 differs); run setup again")
    with open(layout.record) as f:
        return json.load(f)


def run(args) -> int:
    layout = layout_of(args.venv)
    if args.steps <= 0:
        raise Refusal(f"--steps must be positive, got {args.steps}")
    runs_dir = os.path.abspath(args.runs or os.path.join(layout.root, "runs"))
    if inside(runs_dir, REPO):
        raise Refusal(f"--runs {runs_dir} is inside the repository; CleanRL's runs stay outside it")
    todo = plan(layout, args.algo, args.task, parse_seeds(args.seeds), args.steps, runs_dir,
                time.strftime("%Y%m%d-%H%M%S"))
    setup_record = check_setup(layout)
    versions = {name: packages(layout).get(name) for name in VERSIONS}
    record_path = os.path.join(args.out, "run.json")
    record = {"runs": {}}
    if os.path.exists(record_path):
        with open(record_path) as f:
            record = json.load(f)
    record.update(cleanrl=setup_record["cleanrl"], hopper_v5_check=setup_record.get("hopper_v5_check"),
                  final_fraction=FINAL_FRACTION)
    for job in todo:
        name = f"cleanrl-{args.algo}-{slug(args.task)}-seed{job.seed}"
        os.makedirs(job.cwd, exist_ok=True)
        log = os.path.join(job.cwd, "stdout.txt")
        before, start, started = resource.getrusage(resource.RUSAGE_CHILDREN), time.monotonic(), now()
        with open(log, "w") as out:
            code = subprocess.run(job.argv, cwd=job.cwd, env=child_env(layout), stdout=out,
                                  stderr=subprocess.STDOUT).returncode
        wall, after = time.monotonic() - start, resource.getrusage(resource.RUSAGE_CHILDREN)
        if code:
            print(f"error: {name} exited {code}; its output: {log}", file=sys.stderr)
            return 1
        events = sorted(glob.glob(os.path.join(job.cwd, "runs", "**", "events.out.tfevents.*"), recursive=True))
        pairs = venv_json(layout, venv_code.EXTRACT, os.path.dirname(events[-1]), TAG)
        points = [(int(s), float(v)) for s, v in pairs]
        write(os.path.join(args.out, f"{name}.csv"), csv_text(points))
        final = final_return(points, args.steps)
        record["runs"][name] = {
            "algo": args.algo, "task": args.task, "env_id": env_id(args.task), "seed": job.seed, "steps": args.steps,
            "command": job.argv, "cwd": job.cwd, "pythonpath": child_env(layout)["PYTHONPATH"], "events": events[-1],
            "stdout": log, "invocation": ["python", "-m", "experiments.strength.cleanrl", *sys.argv[1:]],
            "started": started, "wall_s": round(wall, 2), "cpu_user_s": round(after.ru_utime - before.ru_utime, 2),
            "cpu_sys_s": round(after.ru_stime - before.ru_stime, 2), "episodes": len(points), "final_return": final,
            "packages": versions, "machine": machine()}
        write(record_path, json.dumps(record, indent=1) + "\n")
        shown = "none" if final is None else f"{final:.1f}"
        print(f"{name}: {args.steps:,} steps in {wall:.1f} s ({1000 * wall / args.steps:.2f} s per 1,000 steps), "
              f"{len(points)} episodes, final return {shown}")
    return 0


def build_parser() -> Parser:
    parser = Parser(prog="python -m experiments.strength.cleanrl", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", parser_class=Parser)
    s = sub.add_parser("setup", help="make the venv and copy CleanRL's files into it")
    s.add_argument("--venv", required=True, help="the venv's folder, outside the repository")
    s.add_argument("--cleanrl", help="a clone of vwxyzjn/cleanrl (default $CLEANRL_REPO)")
    s.add_argument("--python", help="Python 3.12 to make the venv with (default: this one)")
    r = sub.add_parser("run", help="run CleanRL's file once per seed and store its returns")
    r.add_argument("--venv", required=True, help="a venv that setup made")
    r.add_argument("--algo", required=True, help="td3 or sac")
    r.add_argument("--task", required=True, help="hopper or dmc:<domain>-<task>")
    r.add_argument("--seeds", default="1,2,3", help="comma-separated seeds (default 1,2,3)")
    r.add_argument("--steps", type=int, default=300_000, help="--total-timesteps (default 300000)")
    r.add_argument("--out", required=True, help="folder of the CSVs and run.json")
    r.add_argument("--runs", help="CleanRL's run folders, outside the repository (default VENV/runs)")
    return parser


def main(argv: list[str] | None = None) -> int:
    try:
        args = build_parser().parse_args(argv)
        if args.command is None:
            raise Refusal("a command: setup or run")
        return setup(args) if args.command == "setup" else run(args)
    except Refusal as err:
        print(f"error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
