"""The README's two commands are what CI runs, every link in the README and docs/ resolves, and the
plug-in examples (the README's explorer, docs/running.md's student) train."""

import os
import re

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DOCS = [os.path.join("docs", f) for f in sorted(os.listdir(os.path.join(ROOT, "docs"))) if f.endswith(".md")]


def read(path):
    with open(os.path.join(ROOT, path)) as f:
        return f.read()


def indented_commands(text):
    return [line.strip() for line in text.splitlines() if line.startswith("    ") and line.strip()]


def test_readme_starts_with_the_main_job_and_the_test_command_ci_runs():
    commands = indented_commands(read("README.md"))[:2]
    assert commands[0] == "pip install -e . && python -m experiments.run --env=inverted_double_pendulum --seeds=8"
    assert commands[1] == 'pip install -e ".[dev]" && python -m pytest -q -n 2 --dist loadfile --no-loadscope-reorder'
    ci = [line.strip() for line in read(".ci/run").splitlines()]
    marker = ci.index("# --- the README's test command (keep the two in sync) ---")
    assert ci[marker + 1] == commands[1], "README's test command and the one .ci/run runs differ"
    assert 'for python in python3 "$py312"; do' in ci, ".ci/run runs the suite on Python 3.11 and 3.12"


def anchors(markdown):
    """GitHub's heading anchors: lower case, punctuation dropped, spaces to hyphens."""
    out = set()
    for line in markdown.splitlines():
        m = re.match(r"#+ (.*)", line)
        if m:
            slug = re.sub(r"[^\w\- ]", "", m.group(1).strip().lower()).replace(" ", "-")
            out.add(slug)
    return out


@pytest.mark.parametrize("doc", ["README.md", *DOCS])
def test_every_relative_link_resolves(doc):
    text = read(doc)
    base = os.path.dirname(doc)
    links = re.findall(r"\]\(([^)\s]+)\)", text)
    assert links or doc != "README.md"
    for link in links:
        if re.match(r"[a-z]+://", link):
            continue
        path, _, anchor = link.partition("#")
        target = os.path.normpath(os.path.join(base, path)) if path else doc
        assert os.path.exists(os.path.join(ROOT, target)), f"{doc}: {link} -> {target} does not exist"
        if anchor and target.endswith(".md"):
            assert anchor in anchors(read(target)), f"{doc}: no heading for #{anchor} in {target}"


def test_readme_links_every_doc():
    readme = read("README.md")
    for doc in DOCS:
        assert f"]({doc})" in readme, f"README does not link {doc}"


def test_console_scripts_are_the_modules_main_functions():
    """``metapg-run`` etc. (pyproject's [project.scripts]) call the ``main`` that ``python -m`` runs."""
    import importlib
    import tomllib

    with open(os.path.join(ROOT, "pyproject.toml"), "rb") as f:
        scripts = tomllib.load(f)["project"]["scripts"]
    assert {"metapg-run", "metapg-reproduce", "metapg-export"} <= scripts.keys()
    for name, target in scripts.items():
        module, _, func = target.partition(":")
        assert name == "metapg-" + module.split(".")[-1] and func == "main", (name, target)
        assert callable(getattr(importlib.import_module(module), func))


@pytest.mark.slow
@pytest.mark.parametrize("example", ["explorer", "student"])
def test_the_plugin_examples_of_the_readme_and_running_md_train(example, monkeypatch):
    import dataclasses

    import jax

    from metapg_jax.train import make_train, seed_keys, vmap_seeds
    from tests.helpers import isolated_registry

    isolated_registry(monkeypatch)  # no registration leaks out
    if example == "explorer":  # the README's library example, up to its 8-seed training
        code = re.search(r"```python\n(.*?)```", read("README.md"), re.S).group(1)
        code = code[:code.index("trainer = make_train")]
    else:
        text = read("docs/running.md")
        code = re.search(r"```python\n(.*?)```", text[text.index("## Writing an explorer or a student"):], re.S).group(1)
    namespace = {}
    exec(code, namespace)
    cfg = namespace["cfg"]
    cfg = cfg.replace(run=dataclasses.replace(cfg.run, total_steps=600, eval_every=300, eval_episodes=1),
                      meta=dataclasses.replace(cfg.meta, hidden=(16, 16)), ddpg=dataclasses.replace(cfg.ddpg, hidden=(16, 16)))
    trainer = make_train(cfg)
    if example == "student":
        assert type(trainer.student).__name__ == "HuberDDPG"
    state = jax.jit(vmap_seeds(trainer.init))(seed_keys(0, 2))
    state, metrics = jax.jit(vmap_seeds(trainer.train_chunk))(state)
    assert metrics["eval_return"].shape == (2, 1) and int(state.env_steps[0]) == 300
    assert np.all(np.asarray(metrics["cycle"]["finite"]))
