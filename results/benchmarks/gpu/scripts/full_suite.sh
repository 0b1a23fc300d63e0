#!/bin/bash
# GPU check (session 11): the whole test suite (the README's test command, minus the install) on the GPU,
# 12 pytest-xdist workers on the device's 16 cores. JAX_PLATFORMS=cuda,cpu: the default backend is the GPU,
# the CPU stays visible for the export test's pure_callback. Modules the device image lacks are reported first;
# their test files then show as collection errors (--continue-on-collection-errors keeps the rest running).
# Arguments, if any, replace the test selection (the second call reran the first call's failures after the fix).
export PYTHONUNBUFFERED=1 MUJOCO_GL=disable XLA_PYTHON_CLIENT_PREALLOCATE=false
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
export PYTHONPATH=/tmp/site:$PWD JAX_PLATFORMS=cuda,cpu
L=$OUT/full_suite.log; [ $# -gt 0 ] && L=$OUT/full_suite_rerun.log
{ date -u; nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader; nproc
  python3 -c "import jax;print('jax',jax.__version__,jax.devices(),jax.default_backend())"
  for m in flax optax chex brax mujoco orbax.checkpoint gymnasium numpy scipy sklearn matplotlib tqdm pytest xdist nbclient nbformat ipykernel; do
    python3 -c "import $m;print('$m',getattr($m,'__version__','?'))" 2>/dev/null || echo "$m MISSING"; done
} 2>&1 | tee $L
timeout 480 python3 -m pytest -p no:cacheprovider -q -n 12 -rfEs --durations=15 --continue-on-collection-errors \
  --junitxml=$OUT/full_suite_junit.xml "${@:-tests}" 2>&1 | grep -v settotalmass | tail -n 120 | tee -a $L
echo "pytest rc=${PIPESTATUS[0]} $(date -u +%T)" | tee -a $L
