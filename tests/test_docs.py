"""The README's two commands are what CI runs, and every link in the README and docs/ resolves."""

import os
import re

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
    assert commands[1] == 'pip install -e ".[dev]" && python -m pytest -q -n 2'
    ci = [line.strip() for line in read(".ci/run").splitlines() if line.strip() and not line.startswith("#")]
    assert ci[-1] == commands[1], "README's test command and .ci/run's last command differ"


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


def test_the_explorer_example_of_running_md_trains(monkeypatch):
    import dataclasses

    import jax

    from metapg_jax import config as config_lib
    from metapg_jax import explorers
    from metapg_jax.train import make_train, seed_keys, vmap_seeds

    monkeypatch.setattr(explorers, "_FACTORIES", dict(explorers._FACTORIES))  # no registration leaks out
    monkeypatch.setattr(config_lib, "_REGISTERED_METHODS", set(config_lib._REGISTERED_METHODS))
    text = read("docs/running.md")
    block = text[text.index("## Writing an explorer"):]
    namespace = {}
    exec(re.search(r"```python\n(.*?)```", block, re.S).group(1), namespace)
    cfg = namespace["cfg"]
    cfg = dataclasses.replace(cfg, run=dataclasses.replace(cfg.run, total_steps=400, eval_every=200, eval_episodes=1))
    trainer = make_train(cfg)
    state = jax.jit(vmap_seeds(trainer.init))(seed_keys(0, 2))
    state, metrics = jax.jit(vmap_seeds(trainer.train_chunk))(state)
    assert metrics["eval_return"].shape == (2, 1) and int(state.env_steps[0]) == 200
