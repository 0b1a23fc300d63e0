"""The two tiers of the suite (docs/development.md#tests): the full suite, and the fast tier
``python -m pytest -q -n 2 -m "not slow"``, which leaves out the tests marked ``slow`` but keeps every test
module: each tests/test_*.py has a test that is not marked slow, but for the modules named in ALL_SLOW,
whose every test is slow by the rule (and which say why). A module that loses its last fast test, or an
exception that gains one, fails here."""

import os
import subprocess
import sys
import tomllib

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ALL_SLOW = {
    "test_ray.py": "its one test starts a local Ray instance and kills its workers",
    "test_notebooks.py": "its one test runs the notebook in a Jupyter kernel, which compiles its own programs",
}


def _test_modules() -> set:
    return {f for f in os.listdir(os.path.join(ROOT, "tests")) if f.startswith("test_") and f.endswith(".py")}


def _modules_with_a_fast_test(collected) -> set:
    """The test files with a test not marked slow: from this session's collection when it holds every test
    module but those of ALL_SLOW, which may skip at import (the README's command and the fast tier), else from
    a collection with -m "not slow" of its own (this file alone, say)."""
    if {name for name, _ in collected} >= _test_modules() - set(ALL_SLOW):
        return {name for name, slow in collected if not slow}
    proc = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-m", "not slow", "-p", "no:xdist",
                           "-p", "no:cacheprovider", "tests"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return {os.path.basename(line.split("::")[0]) for line in proc.stdout.splitlines() if "::" in line}


def test_every_test_module_keeps_a_test_in_the_fast_tier(collected_tests):
    fast = _modules_with_a_fast_test(collected_tests)
    assert "test_tiers.py" in fast
    assert set(ALL_SLOW) <= _test_modules(), "ALL_SLOW names a module that is gone"
    assert _test_modules() - fast == set(ALL_SLOW), (
        f"modules without a fast test: {sorted(_test_modules() - fast)}; allowed: {sorted(ALL_SLOW)}")


def test_the_slow_marker_is_registered_and_misspelt_markers_are_errors():
    with open(os.path.join(ROOT, "pyproject.toml"), "rb") as f:
        options = tomllib.load(f)["tool"]["pytest"]["ini_options"]
    assert "--strict-markers" in options["addopts"].split()  # @pytest.mark.slwo fails collection
    assert [m for m in options["markers"] if m.startswith("slow:")]
