"""experiments.verify: a stored cell re-run from a clean checkout of its commit gives its numbers back, and a
tampered one is caught; the manifest and footers report the check."""

import json
import os
import subprocess
import sys

import pytest

from experiments import verify
from experiments.analysis import cells
from tests.helpers import TINY_BUFFER, TINY_RUN

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# The command-line tests' tiny run (its programs are in the session's compile cache).
ARGV = [*TINY_RUN, *TINY_BUFFER, "--steps=600", "--no-plot", "--quiet"]


@pytest.mark.slow
def test_a_cell_rerun_at_its_commit_is_reproduced_and_a_changed_one_differs(tmp_path):
    # The stored cell: the command run from a clean checkout of HEAD (what verify runs too), recorded as
    # reproduce does, so the test holds whatever the working tree has uncommitted.
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                          check=True).stdout.strip()
    src, cell = tmp_path / "src", tmp_path / "cell"
    subprocess.run(["git", "worktree", "add", "--detach", "-f", str(src), head], cwd=ROOT, check=True,
                   capture_output=True)
    try:
        env = {**os.environ, "PYTHONPATH": str(src)}
        subprocess.run([sys.executable, "-m", "experiments.run", *ARGV, "--out", str(cell)], cwd=src, env=env,
                       check=True, capture_output=True)
    finally:
        subprocess.run(["git", "worktree", "remove", "--force", str(src)], cwd=ROOT, capture_output=True)
    (cell / "reproduce.json").write_text(json.dumps({"commit": head, "calls": [
        {"argv": [*ARGV, "--out", "runs/somewhere"], "commit": head, "dirty": True}]}))

    assert verify.main([str(cell), "--chunks", "2", "--keep", str(tmp_path / "kept")]) == 0
    record = json.loads((cell / "verified.json").read_text())
    assert record["verdict"] == "reproduced" and record["commit"] == head and record["env_steps"] == 600
    assert record["same_cpu"] is True  # the cell's config.json holds this machine's CPU fingerprint
    assert record["same_packages"] is True  # ... and these package versions
    assert [(r["seed"], r["chunk"]) for r in record["rows"]] == [(0, 0), (0, 1), (1, 0), (1, 1)]
    assert "--steps=600" in record["command"] and "runs/somewhere" not in record["command"]
    r = cells.load_run(str(cell), "pendulum", "meta-independent")
    assert cells.cell_provenance(r)["verified"]["verdict"] == "reproduced"
    assert "1 reproduced the stored numbers." in cells.dirty_summary([r])

    # as if the uncommitted changes had changed training: one number off
    from metapg_jax.host.runfiles import read_jsonl

    stored, rerun = read_jsonl(str(cell / "metrics.jsonl")), read_jsonl(str(tmp_path / "kept" / "run" / "metrics.jsonl"))
    assert verify.compare(stored, rerun, 2, 1e-5)["verdict"] == "reproduced"
    stored[1]["critic_loss"] *= 1.001
    assert verify.compare(stored, rerun, 2, 1e-5)["verdict"] == "differs"
    assert verify.compare(stored, rerun, 1, 1e-5)["verdict"] == "differs"  # row 1 is seed 1, chunk 0
    assert verify.compare(stored, rerun[:1], 1, 1e-5)["verdict"] == "differs"  # a seed missing
    (cell / "verified.json").write_text(json.dumps({**record, "verdict": "differs"}))
    assert "did not (pendulum/meta-independent)" in cells.dirty_summary([cells.load_run(str(cell), "pendulum",
                                                                                   "meta-independent")])
    # an extension from a dirty tree trains code the first intervals never ran: said, not counted as checked
    stored_cfg = json.loads((cell / "config.json").read_text())
    stored_cfg["extensions"] = [{"from_steps": 600, "to_steps": 900, "commit": head, "dirty": True}]
    (cell / "config.json").write_text(json.dumps(stored_cfg))
    extended = cells.load_run(str(cell), "pendulum", "meta-independent")
    assert cells.dirty_after_start(extended)
    assert "1 ran a resumed call or a budget extension from a dirty tree" in cells.dirty_summary([extended])


def test_bad_input_is_one_line(tmp_path, capsys):
    assert verify.main([str(tmp_path)]) == 2
    assert "not a stored cell" in capsys.readouterr().err
