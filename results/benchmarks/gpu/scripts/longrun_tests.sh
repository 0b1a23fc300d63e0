#!/bin/bash
# GPU check (session 9): the long-run guarantees (bit-for-bit resume, budget extension, corrupted-checkpoint
# fallback, policy export) and the chunked-vs-single-scan equality, run by pytest on the GPU.
export PYTHONUNBUFFERED=1 MUJOCO_GL=disable
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
export PYTHONPATH=/tmp/site:$PWD JAX_PLATFORMS=cuda
L=$OUT/gpu_tests.log
{ date -u; nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader; nproc
  python3 -c "import jax,flax,optax,brax,mujoco,pytest;print('jax',jax.__version__,'flax',flax.__version__,'brax',brax.__version__,'mujoco',mujoco.__version__,'pytest',pytest.__version__);print(jax.devices(), jax.default_backend())"
} 2>&1 | tee $L
timeout 420 python3 -m pytest -p no:cacheprovider -q -rA --durations=0 \
  tests/test_longrun.py -k "resume_continues or extend or extension or corrupted or exported" \
  2>&1 | grep -v settotalmass | tail -n 60 | tee -a $L
echo "pytest rc=${PIPESTATUS[0]} $(date -u +%T)" | tee -a $L
timeout 120 python3 -m pytest -p no:cacheprovider -q -rA tests/test_train.py -k "chunked_and_single" \
  2>&1 | grep -v settotalmass | tail -n 20 | tee -a $L
echo "pytest rc=${PIPESTATUS[0]} $(date -u +%T)" | tee -a $L
