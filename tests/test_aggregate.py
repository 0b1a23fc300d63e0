"""experiments.normalisation (the anchors of the normalised scores) and experiments.aggregate (a grid's
aggregate scores over tasks), on a fabricated grid and on Pendulum's random policy."""

import json
import os

import numpy as np
import pytest

from experiments import aggregate, normalisation
from experiments.analysis import stats


def _grid():
    """A grid's JSON twin as experiments.analysis.tables writes it: three tasks, a teacher and two noise baselines; the
    teacher has no finished cell on the third task."""
    rng = np.random.default_rng(3)
    cell = lambda mean: {"status": "done", "per_seed": (mean + rng.normal(0, 0.2, 6)).tolist(), "mean": mean}
    rows = [{"task": "pendulum", "methods": {"meta-independent": cell(-150.0), "ddpg-paramnoise": cell(-200.0),
                                             "ddpg-normal": cell(-180.0)}},
            {"task": "reacher", "methods": {"meta-independent": cell(-5.0), "ddpg-paramnoise": cell(-7.0),
                                            "ddpg-normal": cell(-6.0)}},
            {"task": "hopper", "methods": {"meta-independent": {"status": "not run"}, "ddpg-paramnoise": cell(900.0),
                                           "ddpg-normal": cell(1000.0)}}]
    for row in rows:  # a method the grid planned but never finished
        row["methods"]["meta-variance"] = {"status": "not run"}
    return {"preset": "paper", "baseline": "ddpg-paramnoise", "rows": rows}


ANCHORS = {"pendulum": (-1200.0, -200.0), "reacher": (-43.0, -7.0), "hopper": (18.0, 1264.0)}


def test_the_report_normalises_pools_the_common_tasks_and_compares_teachers_with_noise():
    grid = _grid()
    rep = aggregate.report(grid, ANCHORS)
    assert rep["tasks"] == ["pendulum", "reacher"]
    assert rep["left_out"] == ["Hopper (no finished cell for Meta (independent))"]
    assert rep["absent_methods"] == ["meta-variance"] and "meta-variance" not in rep["methods"]
    pooled = np.concatenate([stats.normalise(row["methods"]["ddpg-normal"]["per_seed"], *ANCHORS[row["task"]])
                             for row in grid["rows"][:2]])
    assert rep["methods"]["ddpg-normal"]["IQM"]["point"] == pytest.approx(stats.iqm(pooled))
    assert rep["methods"]["ddpg-normal"]["optimality gap"]["point"] == pytest.approx(stats.optimality_gap(pooled))
    assert rep["methods"]["ddpg-normal"]["seeds_per_task"] == [6, 6]
    assert [(p["x"], p["y"]) for p in rep["improvement"]] == [("meta-independent", "ddpg-paramnoise"),
                                                              ("meta-independent", "ddpg-normal")]
    better = rep["improvement"][0]  # the means are ten stds and more apart on both tasks
    assert better["point"] == 1.0 and better["lo"] <= better["point"] <= better["hi"]
    assert better["per_task"] == [1.0, 1.0]
    md = aggregate.markdown(rep, "paper preset")
    assert "| Meta (independent) | DDPG (param noise) | 1.00 [1.00, 1.00] | 1.00, 1.00 |" in md
    # a report written before the per-task terms existed still renders, without their column
    old = {**rep, "improvement": [{k: v for k, v in p.items() if k != "per_task"} for p in rep["improvement"]]}
    assert "| Meta (independent) | DDPG (param noise) | 1.00 [1.00, 1.00] |\n" in aggregate.markdown(old, "paper")
    assert "Left out: Hopper (no finished cell for Meta (independent))." in md
    assert "Methods of the grid without a finished cell: Meta (variance)." in md
    with pytest.raises(ValueError, match="no task has a finished cell for every method"):
        aggregate.report(grid, {"hopper": ANCHORS["hopper"]})


def test_the_profiles_thresholds_reach_the_highest_score():
    """0 to 2 unless a seed scores higher; then up to the next quarter above it, so every profile reaches 0."""
    low = {"a": [np.array([0.2, 1.1]), np.array([1.9])], "b": [np.array([-0.5])]}
    assert aggregate.profile_taus(low) is aggregate.PROFILE_TAUS
    taus = aggregate.profile_taus({**low, "c": [np.array([0.4]), np.array([2.48, 1.0])]})
    assert taus[0] == 0.0 and taus[-1] == 2.5 and len(taus) == len(aggregate.PROFILE_TAUS)
    point, _, _ = stats.performance_profile([np.array([0.4]), np.array([2.48, 1.0])], taus, reps=10)
    assert point[-1] == 0.0 and point[0] == 1.0


def test_the_command_writes_the_report_and_refuses_missing_files(tmp_path, capsys):
    grid_path, anchors_path = tmp_path / "table2.json", tmp_path / "anchors.json"
    grid_path.write_text(json.dumps(_grid()))
    anchors_path.write_text(json.dumps({"tasks": {t: {"random_return": lo, "reference_return": hi}
                                                  for t, (lo, hi) in ANCHORS.items()}}))
    assert aggregate.main([str(grid_path), "--anchors", str(anchors_path)]) == 0
    assert sorted(os.listdir(tmp_path)) == ["aggregate.json", "aggregate.md", "anchors.json",
                                            "performance_profiles.png", "table2.json"]
    written = json.loads((tmp_path / "aggregate.json").read_text())
    assert written["tasks"] == ["pendulum", "reacher"] and written["built"]["commit"]
    assert f"at commit {written['built']['commit'][:7]}" in (tmp_path / "aggregate.md").read_text()
    assert aggregate.main([str(grid_path), "--anchors", str(tmp_path / "none.json")]) == 2
    assert "anchors file" in capsys.readouterr().err
    reversed_anchors = tmp_path / "reversed.json"
    reversed_anchors.write_text(json.dumps({"tasks": {"pendulum": {"random_return": 0.0, "reference_return": -1.0}}}))
    assert aggregate.main([str(grid_path), "--anchors", str(reversed_anchors)]) == 2
    assert "pendulum: the reference return -1.0 is not above the random policy's 0.0" in capsys.readouterr().err
    broken = tmp_path / "broken.json"
    broken.write_text(json.dumps({"rows": [{"task": "pendulum"}]}))
    assert aggregate.main([str(broken), "--anchors", str(anchors_path)]) == 2
    assert "needs the field 'methods'" in capsys.readouterr().err


def test_the_random_policys_returns_anchor_zero(tmp_path, capsys):
    ret, length, engine = normalisation.random_policy_returns("pendulum", episodes=4)
    assert engine == "mjx" and ret.shape == (4,) and np.all(length == 200)
    assert len(set(ret.tolist())) == 4 and np.all(ret < -500)  # random swinging: far below a balancing policy
    again, _, _ = normalisation.random_policy_returns("pendulum", episodes=4)
    np.testing.assert_array_equal(ret, again)  # seeded
    out = tmp_path / "anchors.json"
    assert normalisation.main(["--tasks", "pendulum", "--episodes", "4", "--out", str(out)]) == 0
    stored = json.loads(out.read_text())
    assert stored["tasks"]["pendulum"]["random_return"] == pytest.approx(float(ret.mean()))
    assert stored["tasks"]["pendulum"]["reference_run_commit"] and stored["measured"]["commit"]
    low, high = normalisation.load(str(out))["pendulum"]
    assert low == pytest.approx(float(ret.mean())) and high > low
    for argv, message in ((["--tasks", "walker"], "unknown task(s) walker"), (["--episodes", "1"], "at least 2"),
                          (["--tasks", "dmc:cartpole-fly"], "unknown task 'dmc:cartpole-fly'"),
                          (["--tasks", "pendulum,dmc:cartpole-swingup"], "pass them without the Table 2 tasks")):
        assert normalisation.main([*argv, "--out", str(tmp_path / "x.json")]) == 2
        assert message in capsys.readouterr().err
    assert normalisation.main(["--tasks", "dmc:cartpole-swingup"]) == 2  # not into Table 2's file
    assert "holds Table 2's anchors" in capsys.readouterr().err
    assert not (tmp_path / "x.json").exists()


def test_fixed_references_are_the_dmc_maximum_and_mountain_cars_solved_threshold(tmp_path, capsys):
    """A DeepMind Control task: 0 = the random policy's return over whole 1,000-step episodes (never ended early),
    1 = the suite's maximum, 1,000. MountainCarContinuous: 1 = gymnasium's solved threshold, 90; a random policy
    pays the action cost (0.1 a^2 per step, E[a^2] = 1/3 for uniform actions) and rarely reaches the flag."""
    pytest.importorskip("dm_control")
    out = tmp_path / "hard.json"
    assert normalisation.main(["--tasks", "mountain_car_continuous,dmc:pendulum-swingup", "--episodes", "2",
                               "--out", str(out)]) == 0
    stored = json.loads(out.read_text())
    task = stored["tasks"]["dmc:pendulum-swingup"]
    assert task["reference_return"] == 1000.0 and task["random_episode_length_mean"] == 1000.0
    assert 0 <= task["random_return"] < 1000 and task["engine"] == "mujoco" and "maximum" in task["reference"]
    car = stored["tasks"]["mountain_car_continuous"]
    assert car["reference_return"] == 90.0 and "solved threshold" in car["reference"]
    assert -60 < car["random_return"] < 0
    assert "fixed reference" in stored["reference"]["kind"]
    assert normalisation.load(str(out)) == {"dmc:pendulum-swingup": (task["random_return"], 1000.0),
                                            "mountain_car_continuous": (car["random_return"], 90.0)}
    assert normalisation.main(["--tasks", "mountain_car_continuous,hopper", "--out", str(tmp_path / "x.json")]) == 2
    assert "pass them without the Table 2 tasks" in capsys.readouterr().err
    # Table 2's tasks with their own fixed 1 (the dense set normalised as the hard one): Pendulum's maximum, 0,
    # beside MountainCarContinuous's threshold; refused into Table 2's file.
    dense = tmp_path / "dense.json"
    assert normalisation.main(["--fixed-references", "--tasks", "pendulum,mountain_car_continuous", "--episodes", "2",
                               "--out", str(dense)]) == 0
    stored = json.loads(dense.read_text())["tasks"]
    assert stored["pendulum"]["reference_return"] == 0.0 and "maximum" in stored["pendulum"]["reference"]
    assert stored["mountain_car_continuous"]["reference_return"] == 90.0
    assert normalisation.fixed_reference("hopper") is None  # Table 2's anchors keep the grid's cell
    assert normalisation.fixed_reference("hopper", table2_tasks=True)["reference_return"] == 3800.0
    assert normalisation.main(["--fixed-references", "--tasks", "pendulum"]) == 2
    assert "--out results/normalisation-dense.json" in capsys.readouterr().err


def test_a_page_says_what_a_score_of_one_is_from_the_anchors_file(tmp_path):
    """Table 2's file: its DDPG with parameter noise; a file of fixed references: each task's own, grouped by
    reference and limited to the tasks asked for."""
    table2 = tmp_path / "table2.json"
    table2.write_text(json.dumps({"reference": {"grid": "results/table2.json", "method": "ddpg-paramnoise"},
                                  "tasks": {"pendulum": {"random_return": -1200.0, "reference_return": -200.0}}}))
    assert normalisation.describe_reference(str(table2)) == "Table 2's DDPG with parameter noise at the paper's budget"
    other = tmp_path / "other.json"
    other.write_text(json.dumps({"reference": {"grid": "results/td3.json", "method": "td3-normal"}, "tasks": {}}))
    assert normalisation.describe_reference(str(other)) == "the mean final return of `td3-normal` in `results/td3.json`"
    fixed = tmp_path / "fixed.json"
    maximum = "the suite's maximum"
    fixed.write_text(json.dumps({"reference": {"kind": "each task's own fixed reference"}, "tasks": {
        "mountain_car_continuous": {"random_return": -32.0, "reference_return": 90.0, "reference": "solved"},
        "dmc:reacher-hard": {"random_return": 8.0, "reference_return": 1000.0, "reference": maximum},
        "dmc:hopper-hop": {"random_return": 0.0, "reference_return": 1000.0, "reference": maximum}}}))
    assert normalisation.describe_reference(str(fixed), ["mountain_car_continuous", "dmc:reacher-hard"],
                                            str.upper) == (
        "each task's own fixed reference: solved, 90 (MOUNTAIN_CAR_CONTINUOUS); "
        "the suite's maximum, 1,000 (DMC:REACHER-HARD)")
    assert normalisation.describe_reference(str(fixed)).endswith("1,000 (dmc:reacher-hard, dmc:hopper-hop)")
