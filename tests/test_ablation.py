"""experiments.ablation on fabricated run folders: cut at --upto, numbers against hand computation,
config differences read from the stored configs, teacher log-std at its floor, bad input, archive +
rebuild."""

import csv
import json
import os

import numpy as np
import pytest
from scipy import stats

from experiments import ablation
from experiments.analysis import cells
from tests.helpers import fabricate_run

STEPS = np.arange(1, 21) * 1000  # 20 evaluations


def _set_config(path, **changes):
    """Edits a fabricated run's stored config (dotted names), as a --set override would have."""
    p = os.path.join(path, "config.json")
    stored = json.load(open(p))
    for dotted, value in changes.items():
        group, field = dotted.split(".")
        stored["config"][group][field] = value
    json.dump(stored, open(p, "w"))


def _add_teacher_log_std(path, log_stds):
    """Adds a teacher_log_std (per seed, per evaluation) to a fabricated run's metrics.jsonl."""
    p = os.path.join(path, "metrics.jsonl")
    rows = [json.loads(line) for line in open(p)]
    with open(p, "w") as f:
        for r in rows:
            f.write(json.dumps({**r, "teacher_log_std": log_stds[r["seed"]][r["chunk"]]}) + "\n")


@pytest.fixture()
def runs(tmp_path):
    rng = np.random.default_rng(1)
    control = rng.normal(100, 10, (3, 20))
    variant = rng.normal(150, 20, (3, 20))
    fabricate_run(tmp_path / "control", "pendulum", "meta-independent", control, STEPS)
    fabricate_run(tmp_path / "variant", "pendulum", "meta-independent", variant[:, :12], STEPS[:12])
    eval_every = json.load(open(tmp_path / "control" / "config.json"))["config"]["run"]["eval_every"]
    _set_config(tmp_path / "variant", **{"meta.normalize_meta_reward": True, "run.eval_every": eval_every})
    # per evaluation; only those up to --upto (12,000 steps: the first 12) may count
    _add_teacher_log_std(tmp_path / "control", [[-5.0] * 20, [-1.0] * 20, [-4.995] * 11 + [-5.0] + [0.0] * 8])
    _add_teacher_log_std(tmp_path / "variant", [[-0.5] * 11 + [-2.0]] * 3)
    return tmp_path, control, variant


def test_numbers_at_the_common_budget_match_hand_computation(runs):
    root, control, variant = runs
    rows = ablation.compare([(n, cells.load_run(str(root / n))) for n in ("control", "variant")],
                            upto=12000)
    # 12 evaluations up to 12,000 steps -> final = the last 1 (10% of 12, at least 1)
    fin_c, fin_v = control[:, 11], variant[:, 11]
    assert rows[0]["evaluations"] == 12 and rows[0]["final_evaluations"] == 1
    np.testing.assert_allclose(rows[0]["finals"], fin_c)
    np.testing.assert_allclose(rows[1]["finals"], fin_v)
    assert rows[1]["mean"] == pytest.approx(fin_v.mean()) and rows[1]["std"] == pytest.approx(fin_v.std(ddof=1))
    assert rows[1]["p_vs_control"] == pytest.approx(stats.ttest_ind(fin_v, fin_c, equal_var=False).pvalue)
    # one variant: a family of one, so the Holm p is the raw p; the verdict follows it
    assert rows[1]["judged"]["p_holm"] == pytest.approx(rows[1]["p_vs_control"]) and "judged" not in rows[0]
    assert rows[1]["diff"] == {"meta.normalize_meta_reward": (True, False)}  # total_steps ignored
    # teacher: the same window as the final return (the 12th evaluation), not the control's later ones
    assert rows[1]["teacher"]["per_seed"] == [-2.0] * 3 and rows[1]["teacher"]["seeds_at_floor"] == 0
    assert rows[0]["teacher"]["per_seed"] == pytest.approx([-5.0, -1.0, -5.0])
    assert rows[0]["teacher"]["seeds_at_floor"] == 2


def test_report_files_archive_and_rebuild(runs, capsys):
    root, control, variant = runs
    out = root / "report"
    assert ablation.main(["--out", str(out), "--upto", "12000", "--archive",
                          "--run", f"paper preset={root / 'control'}",
                          "--run", f"normalised reward={root / 'variant'}"]) == 0
    md = (out / "README.md").read_text()
    assert "`meta.normalize_meta_reward=true` (control false)" in md
    assert "| 2 of 3 |" in md and "| 0 of 3 |" in md
    assert os.path.exists(out / "curves.png")
    assert sorted(os.listdir(out / "cells" / "normalised-reward")) == [
        "config.json", "metrics.jsonl", "summary.json"]
    with open(out / "per_seed.csv") as f:
        got = list(csv.DictReader(f))
    assert len(got) == 6 and float(got[3]["final_return"]) == pytest.approx(variant[0, 11], abs=1e-3)
    # rebuild from the archived copies alone
    for n in ("control", "variant"):
        os.rename(root / n, root / (n + ".gone"))
    (out / "README.md").unlink()
    assert ablation.main(["--out", str(out), "--rebuild"]) == 0
    assert "normalised reward" in (out / "README.md").read_text()


@pytest.mark.parametrize("args, message", [
    (["--upto", "15000"], "only 12,000 env steps stored"),
    (["--upto", "0"], "--upto must be a positive"),
    ([], "--upto must be a positive"),
])
def test_bad_input_gets_a_clear_error(runs, capsys, args, message):
    root, _, _ = runs
    code = ablation.main(["--out", str(root / "r"), "--run", f"a={root / 'control'}",
                          "--run", f"b={root / 'variant'}", *args])
    assert code == 2 and message in capsys.readouterr().err
    assert not os.path.exists(root / "r")


def test_bad_output_folder_or_manifest_gets_a_clear_error(runs, capsys):
    root, _, _ = runs
    (root / "a_file").write_text("x")
    assert ablation.main(["--out", str(root / "a_file"), "--upto", "12000", "--run", f"a={root / 'control'}",
                          "--run", f"b={root / 'variant'}"]) == 2
    assert "is a file, not a folder" in capsys.readouterr().err
    (root / "not_ablation").mkdir()
    (root / "not_ablation" / ablation.MANIFEST).write_text(json.dumps({"task": "pendulum"}))
    assert ablation.main(["--out", str(root / "not_ablation"), "--rebuild"]) == 2
    assert "is not an ablation manifest (missing 'runs')" in capsys.readouterr().err


def test_run_specs_and_seed_mismatch(runs, capsys):
    root, _, _ = runs
    with pytest.raises(ValueError, match="expected NAME=PATH"):
        ablation.parse_runs(["just-a-path"])
    with pytest.raises(ValueError, match="must differ"):
        ablation.parse_runs(["A b=x", "a-B=y"])
    fabricate_run(root / "two_seeds", "pendulum", "meta-independent", np.zeros((2, 20)), STEPS)
    assert ablation.main(["--out", str(root / "r"), "--upto", "12000", "--run", f"a={root / 'control'}",
                          "--run", f"b={root / 'two_seeds'}"]) == 2
    assert "seeds (2, base 0) differ" in capsys.readouterr().err


def test_config_diff_counts_fields_added_later_at_their_defaults():
    """A control stored before env.physics, td3.* and student existed differs from a new run only in
    what was really changed."""
    from metapg_jax import config as config_lib

    new = config_lib.to_dict(config_lib.make_config("halfcheetah", "meta", overrides={"meta.teacher_steps": 1}))
    old = config_lib.to_dict(config_lib.make_config("halfcheetah", "meta"))
    for key in ("td3", "student"):
        del old[key]
    del old["env"]["physics"]
    assert ablation.config_diff(new, old) == {"meta.teacher_steps": (1, 100)}


def test_the_committed_ablation_rebuilds_from_its_archive_byte_for_byte(tmp_path, monkeypatch):
    """``results/ablations/halfcheetah`` is what ``--rebuild`` builds from its ``cells/`` (the build's
    provenance, stored in ``ablation.json``, pinned); curves.png is written, not compared."""
    import copy
    import json
    import os
    import shutil

    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    folder = os.path.join("results", "ablations", "halfcheetah")
    committed = os.path.join(root, folder)
    with open(os.path.join(committed, "ablation.json")) as f:
        stored = json.load(f)
    shutil.copytree(os.path.join(committed, "cells"), tmp_path / folder / "cells")
    shutil.copy(os.path.join(committed, "ablation.json"), tmp_path / folder / "ablation.json")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(cells, "build_info", lambda out: copy.deepcopy(stored["build"]))
    assert ablation.main(["--out", folder, "--rebuild"]) == 0
    for name in ("README.md", "per_seed.csv", "ablation.json"):
        with open(os.path.join(committed, name), "rb") as f:
            assert (tmp_path / folder / name).read_bytes() == f.read(), name
    assert (tmp_path / folder / "curves.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
