"""experiments.analysis.render.figures: the state-visitation samples, embeddings and figure."""

import numpy as np
import pytest

from experiments import artefacts
from experiments.analysis.render import figures
from tests.helpers import fabricate_run


def test_visitation_groups_keep_only_recorded_states():
    v = {f"{w}_{t}": np.ones((2, 5, 3)) for w in ("explore", "student") for t in ("early", "late")}
    teacher = {**v, "explore_count": np.array([3, 10]), "student_count": np.array([5, 5])}
    ddpg = {**v, "explore_count": np.array([10, 10]), "student_count": np.array([0, 0])}
    groups = figures.visitation_groups(teacher, ddpg)
    assert groups[("early", "teacher")].shape == (3 + 5, 3)
    assert groups[("late", "student")].shape == (10, 3)
    assert groups[("early", "ddpg")].shape == (10, 3)


def test_embeddings_give_two_columns():
    x = np.random.default_rng(0).normal(size=(60, 4))
    for method in ("pca", "tsne"):
        assert figures.embed_2d(x, method).shape == (60, 2)
    assert figures.embed_2d(x[:, :1], "pca").shape == (60, 2)
    with pytest.raises(ValueError, match="unknown embedding"):
        figures.embed_2d(x, "umap")


def test_a_visitation_figure_per_task_with_both_samples(tmp_path):
    """Every task whose Meta (independent) and DDPG baseline cells stored visited states gets a figure
    (default); --visitation-task restricts it; a task without the DDPG cell gets none."""
    rng = np.random.default_rng(2)
    steps = np.arange(1, 6) * 1000
    for task, obs, methods in (("pendulum", 3, ("meta-independent", "ddpg-paramnoise")),
                               ("reacher", 10, ("meta-independent", "ddpg-paramnoise")),
                               ("hopper", 11, ("meta-independent",))):
        for method in methods:
            fabricate_run(tmp_path / "paper" / task / method, task, method, rng.normal(0, 1, (2, 5)), steps,
                          visit_obs=obs)
    tasks = ("pendulum", "reacher", "hopper")
    manifest = artefacts.build_all(str(tmp_path), str(tmp_path / "all"), "paper", tasks=tasks, embedding="pca",
                                   points_per_panel=30)
    assert sorted(f for f in manifest["files"] if f.startswith("visitation_")) == \
        ["visitation_pendulum.png", "visitation_reacher.png"]
    # Rebuilt into the same folder for one task: the other task's figure goes (it is not in the manifest).
    manifest = artefacts.build_all(str(tmp_path), str(tmp_path / "all"), "paper", tasks=tasks, embedding="pca",
                                   points_per_panel=30, visitation_tasks=["reacher", "reacher"])
    assert [f for f in manifest["files"] if f.startswith("visitation_")] == ["visitation_reacher.png"]
    assert not (tmp_path / "all" / "visitation_pendulum.png").exists()
    assert (tmp_path / "all" / "visitation_reacher.png").exists()
    with pytest.raises(SystemExit):
        artefacts.build_parser().parse_args(["--visitation-task", "cartpole"])
