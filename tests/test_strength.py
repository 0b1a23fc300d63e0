"""experiments/strength/cleanrl.py, the runner of CleanRL's files: what it hands them, what it refuses, the final
return it stores, and the env-id hook it writes into CleanRL's venv (no venv is made here: that needs the network)."""

import os
import subprocess
import sys

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
