"""A rebuild from the committed cell archive gives the committed tables and JSON, byte for byte.

``results`` (paper preset), ``results/modern``, ``results/mujoco`` (paper preset on MuJoCo's C engine) and
``results/td3`` (the TD3 grid) and ``results/tuned`` (the tuned preset on the C engine, base seed 100) each hold an archive of finished cells (``cells/<task>/<method>``) and what
``python -m experiments.reproduce --artefacts-only --runs-dir runs/archived-only ...`` built from that
archive alone (``runs/archived-only`` does not exist: every cell is read from the archive). Each is rebuilt
here with ``experiments.artefacts.build_all`` into a tmp folder laid out like the repository (the paths in
the JSON, ``run_dir`` and the manifest's cell ``path``, are relative to the folder the build ran in), and
every ``.md``, ``.json`` and ``.csv`` it writes (tables, ``README.md``, ``manifest.json``) is compared byte
for byte with the committed one.

The numbers are deterministic; the build's provenance (``cells.build_info``: the local time, the commit
and whether the tree had changes, the machine) is not, and it is in the footer of every ``.md``, the
``build_commit`` columns and keys and ``manifest.json``'s ``build``. The test pins it to the committed
manifest's ``build`` (which also holds the ``reproduce`` options recorded then), so that everything else is
compared as written. Figures are not compared (PNG bytes depend on the matplotlib version; the visitation
figure is drawn with PCA here, not the committed t-SNE, to be fast): each one the committed manifest lists
must be written, and nothing else.

Results built from run folders (``runs/reproduce``) carry those folders' paths: rebuild them from the archive
(``--runs-dir runs/archived-only``) before committing them, as this test expects.

The exploration benchmark's grids (``results/exploration``, ``results/first-look`` and the learned-exploration
screens) are checked the same way through ``experiments.analysis.benchmark.build``, with the plan (entries, tasks,
options) their manifest recorded; build them with ``python -m experiments.benchmark ... --artefacts-only`` when
no run folder of theirs exists, so that every cell is read from the archive.
"""

import copy
import json
import os
import shutil

import pytest

from experiments import artefacts
from experiments.analysis import cells

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# committed folder -> (build_all's results_dir, preset) of the build that wrote it
BUILDS = {"results": ("results", "paper"), "results/modern": ("results", "modern"),
          "results/mujoco": ("results/mujoco", "paper"), "results/td3": ("results/td3", "paper"),
          "results/tuned": ("results", "tuned")}


def _first_difference(a: bytes, b: bytes) -> str:
    lines_a, lines_b = a.decode().splitlines(), b.decode().splitlines()
    for i, (x, y) in enumerate(zip(lines_a, lines_b), 1):
        if x != y:
            return f"line {i}:\n  rebuilt:   {x[:300]}\n  committed: {y[:300]}"
    return f"{len(lines_a)} lines rebuilt, {len(lines_b)} committed"


def _compare(names, out, committed: str, folder: str) -> int:
    """Each of ``names`` rebuilt in ``out`` against the committed one: byte for byte (a figure: a PNG only);
    returns how many were compared byte for byte."""
    compared = 0
    for name in names:
        rebuilt = (out / name).read_bytes()
        if name.endswith(".png"):
            assert rebuilt[:8] == b"\x89PNG\r\n\x1a\n", name
            continue
        with open(os.path.join(committed, name), "rb") as f:
            want = f.read()
        assert rebuilt == want, f"{folder}/{name} differs from the rebuild, {_first_difference(rebuilt, want)}"
        compared += 1
    return compared


def _slow_but(folders, ids, fast):
    """The folders as parameters, each marked slow but ``fast``, the smallest of its builder's: the fast tier
    (-m "not slow", tests/test_tiers.py) rebuilds one folder of each builder."""
    return [pytest.param(folder, id=i, marks=() if i == fast else pytest.mark.slow) for folder, i in zip(folders, ids)]


@pytest.mark.parametrize("folder", _slow_but(BUILDS, ["paper", "modern", "mujoco", "td3", "tuned"], "mujoco"))
def test_rebuild_from_the_committed_archive_is_byte_identical(folder, tmp_path, monkeypatch):
    results_dir, preset = BUILDS[folder]
    committed = os.path.join(ROOT, folder)
    with open(os.path.join(committed, "manifest.json")) as f:
        stored = json.load(f)
    build = stored["build"]
    assert build["preset"] == preset
    assert all(c["path"].startswith(f"{folder}/cells/") for c in stored["cells"]), \
        f"{folder} was not built from its archive alone: rebuild it with --runs-dir runs/archived-only"
    shutil.copytree(os.path.join(committed, "cells"), tmp_path / folder / "cells")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(cells, "build_info", lambda runs_dir: copy.deepcopy(build))

    manifest = artefacts.build_all(build["runs_dir"], results_dir, preset, embedding="pca",
                                   student=build.get("student", "ddpg"))

    assert not (tmp_path / build["runs_dir"]).exists()
    assert manifest["files"] == stored["files"]
    out = tmp_path / folder
    written = {str(p.relative_to(out)) for p in out.rglob("*")
               if p.is_file() and p.relative_to(out).parts[0] != "cells"}
    assert written == set(stored["files"]) | {"manifest.json"}
    compared = _compare(sorted(written), out, committed, folder)
    assert compared >= 9  # table2 md/json/csv, steps_to_threshold csv/md, comparisons md/json, README, manifest


# Grids built by ``python -m experiments.benchmark ... --artefacts-only`` (each one's ``--results-dir``). Their
# manifests hold the plan (students, entries, baselines, tasks, options) the build used.
BENCHMARK_BUILDS = ("results/exploration", "results/first-look", "results/learned/screen",
                    "results/learned/screen-sac", "results/learned/judgement",
                    *(f"results/learned/lookahead/steps-{n}" for n in (125, 25, 10)))


@pytest.mark.parametrize("folder", _slow_but(BENCHMARK_BUILDS, ["exploration", "first-look", "screen", "screen-sac", "judgement",
                                                             "lookahead-125", "lookahead-25", "lookahead-10"], "lookahead-125"))
def test_benchmark_rebuild_from_the_committed_archive_is_byte_identical(folder, tmp_path, monkeypatch):
    from experiments.analysis import benchmark as bench_artefacts
    from experiments.analysis.render import benchmark as bench_report

    committed = os.path.join(ROOT, folder)
    with open(os.path.join(committed, "manifest.json")) as f:
        stored = json.load(f)
    build, plan = stored["build"], dict(stored["benchmark"])
    extra = {k: build[k] for k in ("benchmark_wall_seconds",) if k in build}
    entries = [bench_artefacts.Entry(**e) for e in plan.pop("entries")]
    tasks = plan.pop("tasks")
    assert all(c["path"].startswith(f"{folder}/{c['student']}/cells/") for c in stored["cells"]), \
        f"{folder} was not built from its archive alone: rebuild it with --artefacts-only"
    students = stored["benchmark"]["students"]
    for student in students:
        shutil.copytree(os.path.join(committed, student, "cells"), tmp_path / folder / student / "cells")
    kept = [name for name in os.listdir(committed)  # files the build does not write (NOTES.md, packages.txt,
            if os.path.isfile(os.path.join(committed, name)) and name not in stored["files"]]  # diagnostics)
    for name in kept:                              # the README lists those present
        shutil.copy(os.path.join(committed, name), tmp_path / folder / name)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(cells, "build_info", lambda runs_dir: {k: copy.deepcopy(v) for k, v in build.items()
                                                                if k not in extra})

    anchors = os.path.join(ROOT, plan["anchors"]) if "anchors" in plan else None  # a benchmark's --anchors
    manifest = bench_report.build(build["runs_dir"], folder, entries, tasks, plan=plan, anchors_path=anchors,
                                  extra_provenance=extra, preset=plan.get("preset", "paper"))

    assert not (tmp_path / build["runs_dir"]).exists()
    assert manifest["files"] == stored["files"]
    out = tmp_path / folder
    written = {str(p.relative_to(out)) for p in out.rglob("*")
               if p.is_file() and p.relative_to(out).parts[0] not in students}
    assert written == set(stored["files"]) | set(kept)
    compared = _compare(stored["files"], out, committed, folder)
    assert compared >= 3 * len(tasks) + 4  # per task md, json, per-seed csv; cost md and json, README, manifest


def _without_build(path) -> dict:
    with open(path) as f:
        rep = json.load(f)
    rep.pop("built")
    return rep


def test_a_benchmark_renormalised_with_its_own_anchors_is_its_own_aggregate(tmp_path, capsys):
    """The aggregate rebuilt from the built task tables alone (experiments.analysis.render.renormalised) with the
    anchors the benchmark used gives its aggregate.json number for number; bad folders are refused in one line."""
    from experiments.analysis.render import renormalised

    source, out = os.path.join(ROOT, "results", "exploration"), tmp_path / "same"
    assert renormalised.main(["--results-dir", source, "--anchors", os.path.join(ROOT, "results", "normalisation.json"),
                              "--out", str(out)]) == 0
    got, want = _without_build(out / "aggregate.json"), _without_build(os.path.join(source, "aggregate.json"))
    assert got.pop("source")["results_dir"] == "results/exploration" and got == want
    for argv, why in ((["--results-dir", str(tmp_path)], "not a built benchmark"),
                      (["--results-dir", source, "--out", source], "another folder")):
        args = {"--anchors": os.path.join(ROOT, "results", "normalisation.json"), "--out": str(tmp_path / "x"),
                **dict(zip(argv[::2], argv[1::2]))}
        assert renormalised.main([x for kv in args.items() for x in kv]) == 2
        err = capsys.readouterr().err
        assert why in err and err.count("\n") == 1


@pytest.mark.slow
def test_the_committed_renormalised_dense_aggregate_is_rebuilt_number_for_number(tmp_path):
    from experiments.analysis.render import renormalised

    committed = os.path.join(ROOT, "results", "exploration", "dense-renormalised")
    stored = _without_build(os.path.join(committed, "aggregate.json"))
    assert renormalised.main(["--results-dir", os.path.join(ROOT, "results", "exploration"), "--anchors",
                              os.path.join(ROOT, "results", "normalisation-dense.json"), "--out", str(tmp_path)]) == 0
    assert _without_build(tmp_path / "aggregate.json") == stored
