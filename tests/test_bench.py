"""experiments.bench's report writing (the measurements themselves are not unit-tested: timings)."""

import pytest

from experiments import bench


def test_write_section_replaces_only_its_block(tmp_path):
    path = str(tmp_path / "B.md")
    bench.write_section(path, "training", "table v1")
    bench.write_section(path, "env-speed", "env v1")
    with open(path, "a") as f:
        f.write("\n## Hand-written analysis\n\nkeep me\n")
    bench.write_section(path, "training", "table v2")
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
    scaling = bench.seed_scaling(rows)
    assert scaling[id(rows[1])] == 3.0 and scaling[id(rows[4])] == 4.0
    assert id(rows[2]) not in scaling


def test_env_speed_markdown_flags_a_physics_difference():
    meta = {"date": "d", "machine": "m", "jax": "j", "backend": "cpu", "repeats": 3, "json": "x.json"}
    res = [{"task": "pendulum", "num_envs": 8, "steps": 1000, "compile_s": 0.5, "ours_steps_per_s": 1e6,
            "gymnasium_steps_per_s": 5e4},
           {"task": "hopper", "num_envs": 8, "steps": 1000, "compile_s": 30.0, "ours_steps_per_s": 1700.0,
            "stock_steps_per_s": 850.0, "early_exit_speedup": 2.0, "identical_to_stock": False,
            "gymnasium_steps_per_s": 8300.0}]
    md = bench.env_speed_markdown(res, meta)
    assert "| hopper | 1,700 | 850 | 2.00x | NO | 8,300 | 30.0 |" in md
    assert "| pendulum | 1,000,000 | – | – | – | 50,000 | 0.5 |" in md
    assert "| task | ours, 8 envs, steps/s |" in md
    md512 = bench.env_speed_markdown([dict(r, num_envs=512) for r in res], meta)
    assert "| task | ours, 512 envs, steps/s |" in md512 and "512 envs vmapped" in md512


def test_bad_arguments_fail_before_measuring(tmp_path, capsys):
    out = str(tmp_path / "B.md")
    assert bench.main(["--env-speed", "--envs", "pendulum,cartpole", "--out", out]) == 2
    assert "unknown task(s) cartpole" in capsys.readouterr().err
    assert bench.main(["--env-speed", "--envs", "pendulum", "--num-envs", "0", "--out", out]) == 2
    assert "--num-envs and --repeats must be positive" in capsys.readouterr().err
    for argv, message in ((["--methods", "ddpg,sac"], "unknown method 'sac'; valid: ddpg, meta"),
                          (["--presets", "fast"], "unknown preset 'fast'; valid: paper, modern"),
                          (["--seeds", "1,x"], "--seeds must be comma-separated positive integers"),
                          (["--seeds", "0"], "--seeds must be comma-separated positive integers"),
                          (["--target-steps", "0"], "--target-steps must be positive")):
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
