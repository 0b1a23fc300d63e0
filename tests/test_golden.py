"""Short runs of every method give the numbers stored in ``tests/golden_numbers.json`` (``tests/golden.py``).

On a machine like the one that wrote the file (same CPU and JAX version) they must be equal bit for
bit, parameters included: a refactoring of the training loop, the students or the explorers may not
change a single number. Elsewhere XLA may round float32 differently (other vector instructions), so
the returns are compared to a tolerance and the parameter hash is not compared.

The cases in ``CHECKED_ELSEWHERE`` are checked by the tests named there, which run the case's chunks for
checks of their own (``golden.assert_stored``): each case's programs compile once in the suite.
"""

import inspect

import pytest

from tests import golden

CHECKED_ELSEWHERE = {
    "pendulum-ddpg-adaptive-param": "tests.test_train:test_chunked_and_single_scan_agree",
    "pendulum-meta-independent": "tests.test_train:test_chunked_and_single_scan_agree",
    "idp-meta-independent-mujoco": "tests.test_train:test_chunked_and_single_scan_agree",
    "pendulum-meta-independent-td3": "tests.test_td3:test_meta_on_td3_compiles_once_stays_finite_and_gives_its_stored_numbers",
    "pendulum-ddpg-normal-td3": "tests.test_td3:test_td3_trains_as_the_student_of_the_noise_explorer_deterministically",
    "pendulum-own-pink-sac": "tests.test_train:test_chunked_and_single_scan_agree",
    "pendulum-meta-independent-sac": "tests.test_sac:test_meta_on_sac_compiles_once_and_trains_two_chunks_with_finite_numbers",
}


# The fast tier (-m "not slow", tests/test_tiers.py) checks one case, DDPG with Gaussian noise, the simplest program.
FAST_CASE = "pendulum-ddpg-normal"


@pytest.mark.parametrize("name", [pytest.param(name, marks=() if name == FAST_CASE else pytest.mark.slow)
                                  for name in sorted(set(golden.CASES) - set(CHECKED_ELSEWHERE))])
def test_short_runs_give_the_stored_numbers(name):
    golden.assert_stored(name, golden.compute(name))


def test_every_method_has_a_case_and_every_case_is_checked():
    from metapg_jax import strategy
    from metapg_jax.strategies import noise
    from metapg_jax.teacher import designs

    kinds = {(env, method, noise or teacher) for env, method, _, noise, teacher, *_ in golden.CASES.values()}
    for env in ("pendulum",):
        assert {(env, "ddpg", n) for n in noise.names()} <= kinds
        assert {(env, "meta", t) for t in designs()} <= kinds
    assert {case[1] for case in golden.CASES.values()} == set(strategy.explorers())
    assert {case[6] for case in golden.CASES.values() if len(case) > 6} | {"ddpg"} == set(strategy.students())
    assert set(golden.stored()["cases"]) == set(golden.CASES) >= set(CHECKED_ELSEWHERE)
    import importlib

    for name, where in CHECKED_ELSEWHERE.items():  # the test named runs the case and asserts its numbers
        module, function = where.split(":")
        test = getattr(importlib.import_module(module), function)
        cases = [m.args[1] for m in getattr(test, "pytestmark", []) if m.name == "parametrize"]
        source = inspect.getsource(test)
        assert "golden.assert_stored(" in source, where
        assert any(name in c for c in cases) or f'"{name}"' in source, (name, where)
