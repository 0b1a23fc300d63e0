#!/bin/bash
# As run on the device, where it was carried as .whl/gpu_check.sh.
# GPU check for metapg-jax (#5 compute question + README "Backend" claim).
# Device image: python 3.12, jax 0.11.2 + CUDA 13 plugin. Carried wheels: brax 0.14.2, mujoco 4.0.0,
# mujoco-mjx 3.17.0, gymnasium 1.4.0, flax 0.12.12, optax 0.2.8, chex 0.1.92, orbax 0.12.8 (+ small deps).
export PYTHONUNBUFFERED=1 MUJOCO_GL=disable
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
export PYTHONPATH=/tmp/site:$PWD
L=$OUT/gpu.log
{ date -u; nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader; nproc
  python3 -c "import jax,flax,optax,chex,brax,mujoco,numpy,orbax.checkpoint as oc;print('jax',jax.__version__,'flax',flax.__version__,'optax',optax.__version__,'chex',chex.__version__,'brax',brax.__version__,'mujoco',mujoco.__version__,'numpy',numpy.__version__);print(jax.devices(), jax.default_backend())" || exit 2
} 2>&1 | tee $L
[ ${PIPESTATUS[0]} -eq 0 ] || exit 2
one() {  # name timeout args...
  local name=$1 t=$2; shift 2
  echo "=== $name: $* (timeout ${t}s) $(date -u +%T)" | tee -a $L
  timeout $t python3 -m experiments.run --preset=paper --quiet --no-plot --out /tmp/r/$name "$@" 2>&1 | grep -v settotalmass | tee -a $L
  echo "=== $name rc=${PIPESTATUS[0]} $(date -u +%T)" | tee -a $L
  [ -f /tmp/r/$name/summary.json ] && python3 -c "import json,sys;d=json.load(open('/tmp/r/$name/summary.json'));d['name']='$name';print(json.dumps(d))" >> $OUT/summaries.jsonl
  [ -f /tmp/r/$name/metrics.jsonl ] && cp /tmp/r/$name/metrics.jsonl $OUT/metrics_$name.jsonl
}
one hc_ddpg_s8 150 --env=halfcheetah --method=ddpg --noise=adaptive-param --seeds=8 --steps=18000 --set run.eval_every=6000
one hc_meta_s8 180 --env=halfcheetah --method=meta --teacher=independent --seeds=8 --steps=18000 --set run.eval_every=6000
one hc_ddpg_s64 100 --env=halfcheetah --method=ddpg --noise=adaptive-param --seeds=64 --steps=18000 --set run.eval_every=6000
echo done | tee -a $L
