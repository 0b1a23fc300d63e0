"""What a run records about its code (metapg_jax/host/provenance.py): a change to the code makes the tree dirty,
a rewritten results/ file does not, and the diff names the code."""

import os
import shutil

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_provenance_is_dirty_for_code_changes_not_for_rewritten_results(tmp_path):
    import subprocess

    from metapg_jax.host import provenance

    repo = tmp_path / "repo"
    shutil.copytree(os.path.join(ROOT, "metapg_jax"), repo / "metapg_jax")
    (repo / "results").mkdir()
    (repo / "results" / "table.md").write_text("a\n")
    git = lambda *a: subprocess.run(["git", *a], cwd=repo, check=True, capture_output=True)
    git("init", "-q")
    git("add", "-A")
    git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "x")
    import importlib.util

    spec = importlib.util.spec_from_file_location("copied_provenance", repo / "metapg_jax" / "host" / "provenance.py")
    copied = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(copied)  # its record() reads the copy's repository
    assert copied.record()["dirty"] is False and copied.uncommitted_diff() == ""
    (repo / "results" / "table.md").write_text("b\n")  # an output rewritten between cells
    assert copied.record()["dirty"] is False
    (repo / "metapg_jax" / "host" / "provenance.py").write_text((repo / "metapg_jax" / "host" / "provenance.py").read_text() + "\n")
    assert copied.record()["dirty"] is True
    diff = copied.uncommitted_diff()  # the code change, not the rewritten output
    assert "metapg_jax/host/provenance.py" in diff and "table.md" not in diff
    assert provenance.record()["commit"] != copied.record()["commit"]
