#!/bin/bash
# GPU check (session 9, second call): why the exported-policy test fails on the GPU; default matmul
# precision vs JAX_DEFAULT_MATMUL_PRECISION=highest (third call: the test evaluates at "highest" itself).
export PYTHONUNBUFFERED=1 MUJOCO_GL=disable
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
export PYTHONPATH=/tmp/site:$PWD JAX_PLATFORMS=cuda,cpu
L=$OUT/gpu_export.log
for prec in default; do
  echo "=== matmul precision: $prec $(date -u +%T)" | tee -a $L
  if [ $prec = highest ]; then export JAX_DEFAULT_MATMUL_PRECISION=highest; fi
  timeout 200 python3 -m pytest -p no:cacheprovider -q --tb=short tests/test_longrun.py -k "exported" \
    2>&1 | grep -v -i -E "settotalmass|warp" | grep -v "^seed\|^pendulum\|^compiled" | tail -n 40 | tee -a $L
done
