"""The import graph: the pure library (``metapg_jax`` outside ``metapg_jax.host``, and the ``envs`` it builds
on) never imports the host side, nor the libraries that do file, process or terminal I/O."""

import ast
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
HOST_ONLY = ("metapg_jax.host", "tqdm", "matplotlib", "tensorboardX", "wandb", "orbax", "subprocess")
# The optional loggers' packages: imported by their host modules only (tb_events, wandb_runs), nowhere else.
LOGGER_PACKAGES = ("tensorboardX", "wandb")
# ``metapg_jax.load_policy``: the package's lazy alias (its ``__getattr__``), imported only when accessed;
# the last test checks that building and tracing a program does not load it.
ALIASES = {"metapg_jax/__init__.py": {"metapg_jax.host.policy", "metapg_jax.host.policy.load_policy"}}


def _imports(path):
    """Every module an ``import`` or ``from ... import`` statement in the file names (at any depth)."""
    names = set()
    for node in ast.walk(ast.parse(open(path).read(), path)):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
            names.update(f"{node.module}.{alias.name}" for alias in node.names)
    return names


def _pure_modules():
    for package in ("metapg_jax", "envs"):
        for folder, dirs, files in os.walk(os.path.join(ROOT, package)):
            dirs[:] = [d for d in dirs if d not in ("host", "__pycache__")]
            yield from (os.path.join(folder, f) for f in files if f.endswith(".py"))


def test_the_pure_library_imports_nothing_of_the_host_side():
    found = {os.path.relpath(path, ROOT): sorted(name for name in _imports(path)
                                                 if name.split(".")[0] in HOST_ONLY or name.startswith(HOST_ONLY))
             for path in _pure_modules()}
    found = {f: [n for n in names if n not in ALIASES.get(f, ())] for f, names in found.items()}
    assert len(found) > 15 and {f for f in found if f.startswith("metapg_jax/host")} == set()
    assert {f: names for f, names in found.items() if names} == {}


def test_only_the_host_package_imports_the_optional_loggers_packages():
    files = [os.path.join(folder, f) for package in ("metapg_jax", "envs", "experiments", "tests")
             for folder, dirs, names in os.walk(os.path.join(ROOT, package)) for f in names if f.endswith(".py")]
    found = {os.path.relpath(path, ROOT) for path in files
             if any(name.split(".")[0] in LOGGER_PACKAGES for name in _imports(path))}
    assert {"metapg_jax/host/tb_events.py", "metapg_jax/host/wandb_runs.py"} <= found
    assert {f for f in found if not f.startswith(("metapg_jax/host/", "tests/"))} == set()


def test_the_host_package_is_seen_by_the_check():
    """The check above would pass vacuously if it missed imports: the host side's own files trip it."""
    names = _imports(os.path.join(ROOT, "metapg_jax", "host", "terminal.py")) | _imports(
        os.path.join(ROOT, "metapg_jax", "host", "checkpoint.py"))
    assert "tqdm" in names and "orbax.checkpoint" in names


def test_building_and_tracing_a_training_program_loads_no_host_module():
    code = ("import sys, jax\n"
            "from metapg_jax.config import make_config\n"
            "from metapg_jax.train import make_train, seed_keys, vmap_seeds\n"
            "trainer = make_train(make_config('pendulum', 'meta', steps=600, overrides={'run.eval_every': 300}))\n"
            "jax.eval_shape(vmap_seeds(trainer.train), seed_keys(0, 2))\n"
            f"print(sorted(m for m in sys.modules if m.startswith({HOST_ONLY[:-1]!r})))\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().splitlines()[-1] == "[]"


def test_the_package_has_no_import_cycles_and_nothing_imports_a_strategy():
    modules = {}
    for folder, dirs, files in os.walk(os.path.join(ROOT, "metapg_jax")):
        dirs[:] = [d for d in dirs if d != "__pycache__"]
        for f in files:
            if f.endswith(".py") and f != "__init__.py":
                name = os.path.relpath(os.path.join(folder, f[:-3]), ROOT).replace(os.sep, ".")
                modules[name] = os.path.join(folder, f)
    graph = {m: {d for d in _imports(p) if d in modules and d != m} for m, p in modules.items()}
    strategies = {m for m in modules if m.startswith("metapg_jax.strategies.")}
    assert {"metapg_jax.strategies.ddpg", "metapg_jax.strategies.meta", "metapg_jax.strategies.noise",
            "metapg_jax.strategies.td3"} <= strategies
    # Nothing imports a strategy's module (the registry finds them; metapg_jax/strategy.py), and a strategy
    # imports no other: an explorer uses the student through its interface only.
    assert {m: graph[m] & strategies for m in modules if graph[m] & strategies} == {}
    # A student takes the seed-axis helpers from metapg_jax.seeds, not from the loop.
    for student in ("metapg_jax.strategies.ddpg", "metapg_jax.strategies.td3", "metapg_jax.actor_critic"):
        assert "metapg_jax.loop" not in graph[student], student

    state = {}

    def visit(m, path):
        if state.get(m) == "done":
            return
        assert state.get(m) != "open", "import cycle: " + " -> ".join(path + [m])
        state[m] = "open"
        for d in sorted(graph[m]):
            visit(d, path + [m])
        state[m] = "done"

    for m in sorted(graph):
        visit(m, [])


# JAX's private package, spelt in two pieces so that no line here reads as a use of it.
PRIVATE = "jax." + "_src"


def _private_jax(source: str, name: str = "<source>") -> list[str]:
    """Where ``source`` reaches into JAX's private package (``PRIVATE``): an import of it (or of something in it,
    ``from jax import`` it) or an attribute of ``jax`` by its name, as 'line N: what'."""
    found = []
    for node in ast.walk(ast.parse(source, name)):
        names = []
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            names = [node.module] + [f"{node.module}.{alias.name}" for alias in node.names]
        elif isinstance(node, ast.Attribute) and node.attr == "_src" and isinstance(node.value, ast.Name):
            names = [f"{node.value.id}._src"]
        found += [f"line {node.lineno}: {n}" for n in names if n == PRIVATE or n.startswith(PRIVATE + ".")][:1]
    return found


def _notebook_code(path: str) -> str:
    """A notebook's code cells as one Python source (IPython's ``%`` and ``!`` lines left out)."""
    import json

    cells = json.load(open(path))["cells"]
    lines = [line for c in cells if c["cell_type"] == "code" for line in "".join(c["source"]).splitlines()]
    return "\n".join("" if line.lstrip().startswith(("%", "!")) else line for line in lines)


def test_nothing_imports_jax_private_package():
    """JAX's private package may change in any release (jax's API compatibility policy covers only the public
    modules): the code, the studies, the notebooks and the tests use public JAX only."""
    p, sub = PRIVATE, PRIVATE.split(".")[1]
    assert _private_jax(f"from {p} import callback\nimport {p}.core as c\nfrom jax import {sub}\n"
                        f"import jax\n{p}.config\nfrom mujoco.mjx.{sub} import solver\nimport jax.ffi\n") == [
        f"line 1: {p}", f"line 2: {p}.core", f"line 3: {p}", f"line 5: {p}"]
    found, checked = {}, 0
    for package in ("metapg_jax", "envs", "experiments", "tests", "results"):
        for folder, dirs, files in os.walk(os.path.join(ROOT, package)):
            dirs[:] = [d for d in dirs if d != "__pycache__"]
            for f in files:
                path = os.path.join(folder, f)
                if f.endswith((".py", ".ipynb")):
                    checked += 1
                    source = _notebook_code(path) if f.endswith(".ipynb") else open(path).read()
                    hits = _private_jax(source, path)
                    if hits:
                        found[os.path.relpath(path, ROOT)] = hits
    assert checked > 150 and found == {}


MAX_MODULE_LINES = 400


def test_no_module_is_over_400_lines():
    """One responsibility per module: a module past ``MAX_MODULE_LINES`` is split by concern."""
    long = []
    for package in ("metapg_jax", "envs", "experiments"):
        for folder, _, files in os.walk(os.path.join(ROOT, package)):
            for name in files:
                if name.endswith(".py"):
                    path = os.path.join(folder, name)
                    with open(path) as f:
                        lines = sum(1 for _ in f)
                    if lines > MAX_MODULE_LINES:
                        long.append(f"{os.path.relpath(path, ROOT)} ({lines})")
    assert not long, f"modules over {MAX_MODULE_LINES} lines: {', '.join(long)}"
