"""tests/compile_profile.py, the plugin that records where a test's time went: a row per test, with the
compile of a jitted function and the CPU of a subprocess counted."""

import json
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_a_row_per_test_with_its_compile(tmp_path):
    (tmp_path / "test_tiny.py").write_text(
        "import jax, jax.numpy as jnp\n"
        "def test_compiles():\n    assert float(jax.jit(lambda x: jnp.sin(x) * 2)(1.0)) != 0\n"
        "def test_nothing():\n    pass\n"
        "def test_a_child():\n    import subprocess, sys\n"
        "    subprocess.run([sys.executable, '-c', 'sum(i * i for i in range(3_000_000))'], check=True)\n")
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST_")}  # not an xdist worker's
    env.update({"PYTHONPATH": ROOT, "METAPG_COMPILE_PROFILE": str(tmp_path / "profile"),
                "JAX_ENABLE_COMPILATION_CACHE": "false"})
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "tests.compile_profile", "-p", "no:cacheprovider",
                           str(tmp_path / "test_tiny.py")], cwd=str(tmp_path), env=env, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    rows = {r["test"].split("::")[1]: r for r in map(json.loads, open(tmp_path / "profile" / "main.jsonl"))}
    assert set(rows) == {"test_compiles", "test_nothing", "test_a_child"}
    assert rows["test_compiles"]["compile"] > 0 and rows["test_nothing"]["compile"] == 0
    assert rows["test_compiles"]["seconds"] >= rows["test_compiles"]["compile"]
    assert set(rows["test_nothing"]) == {"test", "seconds", "trace", "lower", "compile", "loaded", "compiled", "cpu",
                                         "children_cpu"}
    assert rows["test_compiles"]["cpu"] > 0 and rows["test_nothing"]["children_cpu"] == 0
    assert rows["test_a_child"]["children_cpu"] > 0.05 > rows["test_compiles"]["children_cpu"]
