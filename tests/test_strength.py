"""experiments/strength/cleanrl.py, the runner of CleanRL's files: what it hands them, what it refuses, the final
return it stores, and the env-id hook it writes into CleanRL's venv (no venv is made here: that needs the network)."""

import os
import subprocess
import sys

import numpy as np
import pytest

from experiments.strength import cleanrl
from experiments.strength import cleanrl_venv

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_env_ids_and_the_plan_give_cleanrls_files_only_the_env_the_seed_and_the_budget(tmp_path):
    assert cleanrl.env_id("hopper") == "compat/Hopper-v5"
    assert cleanrl.env_id("dmc:walker-walk") == "dmc-flat/walker-walk-v0"
    with pytest.raises(cleanrl.Refusal, match="unknown task 'halfcheetah'"):
        cleanrl.env_id("halfcheetah")
    with pytest.raises(cleanrl.Refusal):
        cleanrl.env_id("dmc:walker-fly")
    layout = cleanrl.layout_of(str(tmp_path / "venv"))
    (run,) = cleanrl.plan(layout, "sac", "dmc:walker-walk", [7], 300_000, str(tmp_path / "runs"), "stamp")
    assert run.argv == [layout.python, os.path.join(layout.src, "cleanrl/sac_continuous_action.py"), "--env-id",
                        "dmc-flat/walker-walk-v0", "--seed", "7", "--total-timesteps", "300000"]
    assert run.cwd == str(tmp_path / "runs" / "sac-dmc-walker-walk-seed7-stamp")
    with pytest.raises(cleanrl.Refusal, match="unknown algo 'ppo'"):
        cleanrl.plan(layout, "ppo", "hopper", [1], 10, str(tmp_path), "s")
    assert cleanrl.parse_seeds("1,2,3") == [1, 2, 3]
    for bad in ("1,1", "-1", "a"):
        with pytest.raises(cleanrl.Refusal, match="--seeds"):
            cleanrl.parse_seeds(bad)


def test_the_final_return_is_the_mean_of_the_episodes_ending_in_the_last_tenth():
    points = [(100, 1.0), (899, 5.0), (900, 10.0), (950, 20.0), (1000, 30.0)]
    assert cleanrl.final_return(points, 1000) == pytest.approx(20.0)  # 900, 950, 1000
    assert cleanrl.final_return([(10, 1.0)], 1000) is None
    assert cleanrl.csv_text([(12, 9.5)]) == "step,episodic_return\n12,9.5\n"


def test_the_childs_environment_has_cleanrls_tree_and_our_ids_and_none_of_our_settings(monkeypatch, tmp_path):
    monkeypatch.setenv("JAX_PLATFORMS", "cpu")
    monkeypatch.setenv("XLA_FLAGS", "--x")
    monkeypatch.setenv("PYTHONHASHSEED", "0")
    layout = cleanrl.layout_of(str(tmp_path / "venv"))
    env = cleanrl.child_env(layout)
    assert env["PYTHONPATH"] == os.pathsep.join([layout.src, layout.site])
    assert not any(k.startswith(("JAX_", "XLA_", "PYTHONHASH")) for k in env)


def test_refusals_in_one_line(tmp_path, capsys):
    assert cleanrl.main(["setup", "--venv", os.path.join(ROOT, "some-venv"), "--cleanrl", str(tmp_path)]) == 2
    assert "is inside the repository" in capsys.readouterr().err
    assert cleanrl.main(["run", "--venv", str(tmp_path / "venv"), "--algo", "td3", "--task", "hopper",
                         "--out", str(tmp_path / "out")]) == 2
    assert "is not set up" in capsys.readouterr().err
    assert cleanrl.main(["run", "--venv", str(tmp_path / "venv"), "--algo", "td3", "--task", "hopper",
                         "--steps", "0", "--out", str(tmp_path / "out")]) == 2
    assert "--steps must be positive" in capsys.readouterr().err
    assert cleanrl.main([]) == 2 and "setup or run" in capsys.readouterr().err
    assert cleanrl.main(["setup", "--venv", str(tmp_path / "venv")]) == 2
    assert "needs a clone of vwxyzjn/cleanrl" in capsys.readouterr().err


def test_the_env_id_hook_takes_its_folder_off_pythonpath_before_importing_gymnasium(tmp_path):
    """Importing dm_control starts a Python subprocess (glfw's library probe) that inherits PYTHONPATH: with the hook's
    folder still on it, that subprocess would run the hook again, and so on without end."""
    site = tmp_path / "site"
    site.mkdir()
    (site / "sitecustomize.py").write_text(cleanrl_venv.SITECUSTOMIZE)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), "/elsewhere"])}
    out = subprocess.run([sys.executable, "-c", "import os, gymnasium; print(os.environ['PYTHONPATH']); "
                          "print('compat/Hopper-v5' in gymnasium.registry)"], env=env, capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["/elsewhere", "True"]


def test_the_references_episodes_binned_into_our_chunks_and_the_final_return_by_hand():
    from experiments.analysis import strength

    episodes = [(5, 1.0), (10, 3.0), (11, 10.0), (25, 7.0), (31, 99.0)]  # 31: after the last chunk, left out
    binned = strength.bin_episodes(episodes, [10, 20, 30])
    np.testing.assert_array_equal(binned, [2.0, 10.0, 7.0])
    assert np.isnan(strength.bin_episodes([(5, 1.0)], [10, 20])[1])
    # the chunks ending after 90% of 100 steps: 95 and 100 (NaN left out)
    assert strength.final_of(np.array([1.0, 2.0, 4.0, np.nan]), [50, 90, 95, 100], 100) == 4.0
    assert np.isnan(strength.final_of(np.array([1.0, np.nan]), [50, 100], 100))


def _reference(finals):
    """A reference seed per final: one episode ending in each of the 10 chunks, the last one at ``final``."""
    return [[(10 * (c + 1), 0.0 if c < 9 else f) for c in range(10)] for f in finals]


def test_a_difference_beyond_the_seeds_spread_is_named_and_one_within_it_is_not():
    from experiments.analysis import strength

    ends = list(range(10, 101, 10))
    ours = np.zeros((3, 10))
    ours[:, 9] = [100.0, 110.0, 120.0]  # finals: the last chunk only (the last 10% of 100 steps)
    far = strength.compare(_reference([10.0, 20.0, 30.0]), ends, ours, 100)
    assert far["ours"]["finals"] == [100.0, 110.0, 120.0] and far["reference"]["finals"] == [10.0, 20.0, 30.0]
    assert far["difference"] == pytest.approx(90.0) and far["pooled_std"] == pytest.approx(10.0)
    assert far["difference_in_std"] == pytest.approx(9.0) and far["verdict"] == "beyond the seeds' spread"
    lo, hi = far["ours"]["ci95"]
    assert (lo + hi) / 2 == pytest.approx(110.0) and hi - lo == pytest.approx(2 * 4.302653 * 10 / np.sqrt(3), rel=1e-5)
    near = strength.compare(_reference([105.0, 115.0, 125.0]), ends, ours, 100)
    assert near["difference"] == pytest.approx(-5.0) and near["verdict"] == "within the seeds' spread"
    assert strength.compare(_reference([5.0]), ends, ours, 100)["verdict"].startswith("not judged")
    with pytest.raises(ValueError, match="not at the budget 200"):
        strength.compare(_reference([5.0]), ends, ours, 200)


def test_the_comparison_command_writes_its_page_from_csvs_and_a_run_folder(tmp_path, capsys):
    import json

    from experiments.analysis.render.strength import main
    from tests.helpers import fabricate_run

    run = tmp_path / "ours"
    fabricate_run(str(run), "pendulum", "ddpg-normal", [[0.0] * 10] * 2, list(range(1000, 10001, 1000)))
    rows = [json.loads(line) for line in open(run / "metrics.jsonl")]
    with open(run / "metrics.jsonl", "w") as f:
        for r in rows:
            f.write(json.dumps({**r, "train_return": -100.0 * (r["seed"] + 1)}) + "\n")
    for k, final in enumerate((-150.0, -140.0)):
        (tmp_path / f"cleanrl-td3-pendulum-seed{k}.csv").write_text(
            "step,episodic_return\n200,-900.0\n" + f"9500,{final}\n")
    assert main(["--reference", str(tmp_path / "cleanrl-*.csv"), "--ours", str(run), "--name", "td3-pendulum",
                 "--out", str(tmp_path / "out")]) == 0
    assert "td3-pendulum: ours -150, CleanRL -145: within the seeds' spread" in capsys.readouterr().out
    md = (tmp_path / "out" / "td3-pendulum.md").read_text()
    assert "| ours | 2 | -100, -200 | -150 [" in md and "| CleanRL | 2 | -150, -140 | -145 [" in md
    assert (tmp_path / "out" / "td3-pendulum.png").stat().st_size > 0
    assert main(["--reference", str(tmp_path / "nothing-*.csv"), "--ours", str(run), "--name", "x",
                 "--out", str(tmp_path / "out")]) == 2
    assert "--reference matches no file" in capsys.readouterr().err
