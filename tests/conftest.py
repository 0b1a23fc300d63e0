import atexit
import os
import shutil
import tempfile

import pytest

os.environ.setdefault("JAX_PLATFORMS", "cpu")


def _session_compile_cache() -> None:
    """One persistent compile cache for the whole test session, in a folder made for it (never
    ~/.cache, never warm from an earlier pytest run), shared by the xdist workers and the subprocesses
    the tests start (they inherit the variables): a program that several tests compile with the same
    shapes (the tiny runs of tests/helpers.py) compiles once and loads afterwards. The size limit
    makes JAX's cache take its file lock, so workers do not read each other's half-written entries.
    Programs with MuJoCo C engine calls are stored by jax 0.12, not by jax 0.10 (which does not cache
    host callbacks). Tests of the cache itself name their own folders (tests/test_longrun.py)."""
    if os.environ.get("METAPG_TEST_COMPILE_CACHE"):  # an xdist worker: the controller made it
        return
    folder = tempfile.mkdtemp(prefix="metapg-test-xla-")
    os.environ.update({"METAPG_TEST_COMPILE_CACHE": folder, "JAX_COMPILATION_CACHE_DIR": folder,
                       "JAX_ENABLE_COMPILATION_CACHE": "true", "JAX_COMPILATION_CACHE_MAX_SIZE": str(4 * 2**30)})
    atexit.register(shutil.rmtree, folder, ignore_errors=True)


_session_compile_cache()


@pytest.fixture(autouse=True)
def _back_to_the_session_settings():
    """After each test, this process compiles into the pytest run's cache again: a test that runs
    ``experiments.run`` or ``experiments.sweep`` in-process with ``--compile-cache=off`` or a folder of its
    own leaves JAX pointed there, and every later test in that worker would compile afresh. The C engine's
    thread count (``--physics-threads``) goes back to what it was too."""
    threads = os.environ.get("METAPG_PHYSICS_THREADS")
    yield
    from metapg_jax.host import compile_cache

    compile_cache.enable(compile_cache.resolve(None))
    if threads is None:
        os.environ.pop("METAPG_PHYSICS_THREADS", None)
    else:
        os.environ["METAPG_PHYSICS_THREADS"] = threads


# The test modules in order of their total time on 2 cores, the longest first (measured with
# ``-p tests.compile_profile``, results/measurements/test-suite.md). The README's test command hands whole
# modules to the xdist workers (``--dist loadfile --no-loadscope-reorder``: a module's programs, caches and
# session fixtures are built in one worker, not in both) in this order, longest first, so that the short
# modules fill in around the long ones and no worker is left with a long module at the end (the
# modules not named here take a few seconds each).
FIRST = ("test_train.py", "test_envs_mujoco.py", "test_longrun.py", "test_golden.py", "test_physics.py",
         "test_meta.py", "test_sweep.py", "test_dmc.py", "test_multiprocess.py", "test_td3.py", "test_reproduce.py",
         "test_artefacts.py", "test_sac.py", "test_ray.py", "test_cli.py", "test_notebooks.py", "test_gym_tasks.py",
         "test_dmc_locomotion.py", "test_driver.py", "test_wandb.py", "test_verify.py", "test_plugins.py",
         "test_docs.py", "test_screen.py", "test_noise.py", "test_counterfactual.py", "test_tensorboard.py",
         "test_benchmark.py", "test_mountain_car.py", "test_runner.py", "test_signal.py", "test_imports.py",
         "test_strategy.py")


# (test file name, marked slow) of every test collected, before -m or -k deselected any (tests/test_tiers.py).
_COLLECTED: list = []


@pytest.hookimpl(tryfirst=True)  # before pytest's own hook deselects by -m and -k
def pytest_collection_modifyitems(session, config, items):
    _COLLECTED[:] = [(item.path.name, item.get_closest_marker("slow") is not None) for item in items]
    rank = {name: i for i, name in enumerate(FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(FIRST)))  # stable: the rest keep their order


@pytest.fixture
def collected_tests() -> list:
    """(test file name, marked slow) of every test this pytest process collected, -m and -k aside."""
    return list(_COLLECTED)
