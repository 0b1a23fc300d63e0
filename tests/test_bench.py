"""experiments.bench's report writing (the measurements themselves are not unit-tested: timings; a checkpoint's bytes
are)."""

import json

import pytest

from experiments import bench
from experiments.benchmarks import engines, env_speed, records, training


def test_write_section_replaces_only_its_block(tmp_path):
    path = str(tmp_path / "B.md")
    records.write_section(path, "training", "table v1")
    records.write_section(path, "env-speed", "env v1")
    with open(path, "a") as f:
        f.write("\n## Hand-written analysis\n\nkeep me\n")
    records.write_section(path, "training", "table v2")
    text = open(path).read()
    assert "table v2" in text and "table v1" not in text
    assert "env v1" in text and "keep me" in text
    assert text.index("table v2") < text.index("env v1") < text.index("keep me")


def test_seed_scaling_within_one_date_and_variant():
    row = lambda seeds, sps, **kw: {"env": "pendulum", "method": "ddpg", "preset": "paper", "seeds": seeds,
                                    "steps_per_s_total": sps, **kw}
    rows = [row(1, 100.0, measured="2026-11-25"), row(8, 300.0, measured="2026-11-25"),
            row(8, 900.0),  # undated (first run): no 1-seed row of its own date
            row(1, 50.0, measured="2026-11-25", plain_vmap=True), row(8, 200.0, measured="2026-11-25", plain_vmap=True)]
    scaling = training.seed_scaling(rows)
    assert scaling[id(rows[1])] == 3.0 and scaling[id(rows[4])] == 4.0
    assert id(rows[2]) not in scaling


def test_env_speed_markdown_has_both_engines_the_limits_and_the_verdicts():
    meta = {"date": "d", "machine": "m", "jax": "j", "backend": "cpu", "repeats": 3, "json": "x.json"}
    c = {"num_envs": 8, "steps": 1000, "c_threads": 2, "rollout_steps_per_s": 9000.0, "pool_steps_per_s": 8000.0}
    res = [{"task": "pendulum", "num_envs": 8, "steps": 1000, "compile_s": 0.5, "ours_steps_per_s": 1e6,
            "gymnasium_steps_per_s": 5e4},
           {"task": "hopper", **c, "compile_s": 30.0, "ours_steps_per_s": 2000.0, "c_steps_per_s": 12000.0,
            "c_over_mjx": 6.0, "raw_loop_steps_per_s": 13000.0, "c_over_raw_loop": 12000 / 13000,
            "batch_steps_per_s": 20000.0, "c_compile_s": 1.5, "gymnasium_steps_per_s": 8300.0,
            "c_overhead_us_per_step": 266.7},
           {"task": "inverted_double_pendulum", **c, "compile_s": 20.0, "ours_steps_per_s": 10000.0,
            "c_steps_per_s": 12000.0, "c_over_mjx": 1.2, "raw_loop_steps_per_s": 13000.0,
            "c_over_raw_loop": 12000 / 13000, "batch_steps_per_s": 20000.0, "c_compile_s": 1.5,
            "gymnasium_steps_per_s": 8300.0, "stock_steps_per_s": 5000.0, "early_exit_speedup": 2.0,
            "identical_to_stock": False}]
    md = env_speed.env_speed_markdown(res, meta)
    assert "| hopper | 2,000 | 12,000 | 6.00x | 13,000 | 0.92x | 20,000 | 267 | 9,000 | 8,000 | yes | 8,300 | 30.0 / 1.5 |" in md
    # IDP misses its 1.5x-over-MJX target
    assert "| inverted_double_pendulum | 10,000 | 12,000 | 1.20x | 13,000 | 0.92x | 20,000 | – | 9,000 | 8,000 | NO |" in md
    assert "| pendulum | 1,000,000 | – | – | – | – | – | – | – | – | – | 50,000 | 0.5 / – |" in md
    assert "2 threads" in md and "8 envs vmapped" in md
    assert "| inverted_double_pendulum | 5,000 | 2.00x | NO |" in md  # the stock line search column
    assert "on d (m;" in md
    # --physics=mujoco: the C engine's columns alone; the commit measured is named.
    c_only = {k: v for k, v in res[1].items() if k not in ("compile_s", "ours_steps_per_s", "c_over_mjx")}
    md = env_speed.env_speed_markdown([c_only], {**meta, "commit": "0123456789abcdef", "dirty": False})
    assert "| hopper | – | 12,000 | – | 13,000 | 0.92x | 20,000 | 267 | 9,000 | 8,000 | – | 8,300 | – / 1.5 |" in md
    assert "on d at 0123456 (m;" in md


def test_env_speed_measures_a_dmc_task_on_the_c_engine_against_dm_control():
    """--env-speed on a DeepMind Control task: the C engine in the program, its loops outside JAX on dm_control's
    model, and dm_control's own suite as the reference column; a gym: task is refused in one line."""
    pytest.importorskip("dm_control")
    r = env_speed.measure_env_speed("dmc:pendulum-swingup", num_envs=2, steps=20, repeats=1, engines=("mujoco",))
    for k in ("c_steps_per_s", "raw_loop_steps_per_s", "batch_steps_per_s", "gymnasium_steps_per_s"):
        assert r[k] > 0, k
    assert "ours_steps_per_s" not in r and r["c_threads"] >= 1


@pytest.mark.parametrize("argv, message", [
    (["--env-speed", "--envs", "gym:Walker2d-v5"], "--env-speed measures the built-in and dmc: tasks"),
    (["--env-speed", "--envs", "dmc:cartpole-fly"], "unknown task 'dmc:cartpole-fly'"),
])
def test_bench_refuses_tasks_it_cannot_measure(argv, message, capsys):
    from experiments import bench

    assert bench.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err


def test_engines_table_pairs_rows_of_one_date():
    row = lambda physics, sps, date="2026-12-01", **kw: {
        "env": "hopper", "method": "meta", "preset": "paper", "seeds": 8, "measured": date, "physics": physics,
        "steps_per_s_total": sps, "compile_s": 20.0 if physics == "mujoco" else 400.0, "full_s": 10.0,
        "updates_s": 4.0, **kw}
    rows = [row("mjx", 500.0), row("mujoco", 3000.0), row("mujoco", 2500.0, date="2026-12-02")]
    md = "\n".join(engines.engines_markdown(rows))
    assert "| hopper | meta | paper | 8 | 2026-12-01 | 500 | 3,000 | 6.00x | 0.40 | 400.0 / 20.0 |" in md
    assert "| hopper | meta | paper | 8 | 2026-12-02 | – | 2,500 | – | 0.40 | – / 20.0 |" in md
    assert engines.engines_markdown([row("mjx", 500.0)]) == []
    assert records._variant(row("mujoco", 1.0)) == " (MuJoCo C)"


def test_bad_arguments_fail_before_measuring(tmp_path, capsys):
    out = str(tmp_path / "B.md")
    assert bench.main(["--env-speed", "--envs", "pendulum,cartpole", "--out", out]) == 2
    assert "unknown task 'cartpole'" in capsys.readouterr().err
    assert bench.main(["--env-speed", "--envs", "pendulum", "--num-envs", "0", "--out", out]) == 2
    assert "--num-envs and --repeats must be positive" in capsys.readouterr().err
    assert bench.main(["--env-speed", "--envs", "pendulum", "--physics", "mujoco", "--out", out]) == 2
    assert capsys.readouterr().err == "error: --physics=mujoco steps only MuJoCo tasks; --envs names none\n"
    for argv, message in ((["--methods", "ddpg,sac"], "unknown method 'sac'; valid: ddpg, meta, own"),
                          (["--strategies", "td3-brown"], "unknown grid method 'td3-brown'"),
                          (["--presets", "fast"], "unknown preset 'fast'; valid: paper, modern"),
                          (["--seeds", "1,x"], "--seeds must be comma-separated positive integers"),
                          (["--seeds", "0"], "--seeds must be comma-separated positive integers"),
                          (["--target-steps", "0"], "--target-steps must be positive"),
                          (["--physics", "mjx,bullet"], "unknown physics 'bullet'; valid: mjx, mujoco"),
                          (["--checkpoint", "--checkpoint-writes", "0"], "--checkpoint-writes must be positive")):
        assert bench.main([*argv, "--out", out, "--json", str(tmp_path / "b.json")]) == 2, argv
        assert message in capsys.readouterr().err
    assert not (tmp_path / "B.md").exists() and not (tmp_path / "b.json").exists()


def test_replay_benchmark_refuses_sizes_it_cannot_time(capsys):
    from experiments import bench_replay

    for argv in (["--capacity", "50"], ["--cycles", "0"], ["--repeats", "0"], ["--seeds", "0"]):
        with pytest.raises(SystemExit) as exc:
            bench_replay.main(argv)
        assert exc.value.code == 2, argv
    assert "--capacity must hold one cycle's 100 added transitions" in capsys.readouterr().err


def test_replay_benchmark_records_rows_and_replaces_same_day_ones(tmp_path):
    from experiments.benchmarks import replay

    path = str(tmp_path / "replay.json")
    row = lambda buffer, capacity, ms, day="2026-12-01": {"buffer": buffer, "seeds": 8, "capacity": capacity,
                                                         "measured": day, "ms_per_cycle": ms}
    replay.record(path, [row("ring", 100_000, 1.0), row("ring", 100_000, 3.0, "2026-11-23")])
    replay.record(path, [row("ring", 100_000, 2.0), row("flashbax", 100_000, 5.0)])
    with open(path) as f:
        rows = json.load(f)["rows"]
    assert sorted((r["buffer"], r["measured"], r["ms_per_cycle"]) for r in rows) == [
        ("flashbax", "2026-12-01", 5.0), ("ring", "2026-11-23", 3.0), ("ring", "2026-12-01", 2.0)]


def test_every_grid_method_is_a_strategy_the_benchmark_can_measure():
    """``--strategies``: each grid method's options become a valid config with the method's student."""
    from experiments.bench import grid_strategy
    from experiments.grid.methods import METHODS, STUDENT_OF
    from metapg_jax.config import make_config, validate

    for name in METHODS:
        spec = grid_strategy(name)
        cfg = validate(make_config("hopper", spec["method"], student=spec["student"], overrides=spec["overrides"]))
        assert cfg.student == STUDENT_OF.get(name, "ddpg") and spec["label"] == name
    assert grid_strategy("td3-pink")["overrides"] == {"noise.kind": "pink", "noise.stddev": "0.1"}


def test_a_checkpoints_cost_is_measured_empty_and_full_and_tabled_against_the_grace(tmp_path):
    """A tiny run's checkpoints (2 writes each): full buffers hold every row at full entropy, so they take far more
    bytes on disk than empty ones (compressed to almost nothing); the table names each run and the verdict."""
    from experiments.benchmarks import checkpoint

    argv = ["--env=pendulum", "--method=ddpg", "--seeds=2", "--steps=20000", "--set", "ddpg.hidden=16,16"]
    row = checkpoint.measure_checkpoint("tiny", argv, writes=2)
    assert row["buffer_capacity"] == 20_000 and row["seeds"] == 2 and row["physics"] == "mjx"
    assert len(row["empty"]["seconds"]) == len(row["full"]["seconds"]) == 2
    rows_bytes = 2 * 20_000 * (3 + 1 + 1 + 3 + 1 + 1) * 4  # obs, action, reward, next obs, terminated, truncated
    assert row["empty"]["bytes"] < 0.1 * rows_bytes < 0.9 * rows_bytes < row["full"]["bytes"] < 1.5 * row["state_bytes"]
    meta = {"date": "d", "commit": "abcdef0123", "machine": "m", "jax": "j", "backend": "cpu", "conditions": "c",
            "json": "x.json"}
    slow = {**row, "case": "slow", "full": {**row["full"], "median_s": 30.0}}
    md = checkpoint.checkpoint_markdown([row, slow], meta, 25.0)
    assert "| tiny: `--env=pendulum --method=ddpg --seeds=2" in md and "(d, commit abcdef0)" in md
    assert md.endswith("The costliest, slow with full buffers, takes 30.0 s: more than the default --term-grace of "
                       "25 s.")
    assert checkpoint.checkpoint_markdown([row], meta, 25.0).endswith("within the default --term-grace of 25 s.")
    sigterm = [{"grace_s": 0.0, "status": 143, "chunks_before_signal": 3, "signal_into_chunk_s": 1.0, "chunk_s": 14.2,
                "checkpointed_chunks": 0, "exit_after_s": 0.6, "lost_s": 43.5, "last_line": "stopped by SIGTERM: x"}]
    md = checkpoint.sigterm_markdown(sigterm, meta, 150_000)
    assert "| 0 | 14.2 | 1.0 | 143 | 0.6 | none | 43.5 |" in md and "- `--term-grace=0`: stopped by SIGTERM: x" in md


def test_threads_markdown_pairs_each_tasks_thread_counts():
    """--threads' tables: a stepping row with both gains and the program's distance from the threaded batch, and a
    training row per task with both thread counts (a task with one of them only has none)."""
    from experiments.benchmarks import threads

    meta = {"date": "d", "machine": "m", "jax": "j", "threads": 2, "repeats": 3, "json": "t.json",
            "conditions": "quiet", "commit": "0123456789abcdef", "dirty": False}
    step = {"task": "hopper", "num_envs": 8, "program_1": 5000.0, "program_2": 6000.0, "loop_1": 7000.0,
            "batch_1": 8000.0, "batch_2": 12000.0, "threads_gain_in_program": 1.2, "threads_gain_outside": 1.5,
            "program_over_loop": 6000 / 7000, "program_over_threaded_batch": 0.5}
    train = [{"task": "hopper", "threads": 1, "steps_per_s": 3000.0},
             {"task": "hopper", "threads": 2, "steps_per_s": 3300.0},
             {"task": "halfcheetah", "threads": 1, "steps_per_s": 4000.0}]
    md = threads.threads_markdown([step], train, meta)
    assert "| hopper | 8 | 5,000 | 6,000 | 1.20x | 7,000 | 8,000 | 12,000 | 1.50x | 0.86x | 2.00x slower |" in md
    assert "| hopper | 3,000 | 3,300 | 1.10x |" in md and "| halfcheetah |" not in md
    assert "at 0123456 (m;" in md and "quiet" in md
