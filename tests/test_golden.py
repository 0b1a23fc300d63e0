"""Short runs of every method give the numbers stored in ``tests/golden_numbers.json`` (``tests/golden.py``).

On a machine like the one that wrote the file (same CPU and JAX version) they must be equal bit for
bit, parameters included: a refactoring of the training loop, the students or the explorers may not
change a single number. Elsewhere XLA may round float32 differently (other vector instructions), so
the returns are compared to a tolerance and the parameter hash is not compared.
"""

import json

import numpy as np
import pytest

from tests import golden

with open(golden.PATH) as _f:
    STORED = json.load(_f)
SAME_MACHINE = STORED["machine"] == golden.machine()


@pytest.mark.parametrize("name", sorted(golden.CASES))
def test_short_runs_give_the_stored_numbers(name):
    got, want = golden.compute(name), STORED["cases"][name]
    if SAME_MACHINE:
        assert got["eval_return"] == want["eval_return"]
        assert got["student_sha256"] == want["student_sha256"]
    else:
        np.testing.assert_allclose(got["eval_return"], want["eval_return"], rtol=1e-3, atol=1e-3)


def test_every_method_has_a_case():
    from metapg_jax.config import NOISES, TEACHERS

    kinds = {(env, method, noise or teacher) for env, method, _, noise, teacher, *_ in golden.CASES.values()}
    for env in ("pendulum",):
        assert {(env, "ddpg", n) for n in NOISES} <= kinds
        assert {(env, "meta", t) for t in TEACHERS} <= kinds
    assert {case[6] for case in golden.CASES.values() if len(case) > 6} == {"td3"}
    assert set(STORED["cases"]) == set(golden.CASES)
