#!/bin/bash
# GPU check (session 14): (1) the persistent compile cache on the GPU: the same experiments.run twice with one
# --compile-cache folder; (2) the speed cost of --xla_gpu_deterministic_ops=true, which importing metapg_jax adds
# to XLA_FLAGS (README "Backend"): the same measurements with that default and with the opt-out
# XLA_FLAGS=--xla_gpu_deterministic_ops=false, one after the other on the same GPU: experiments.bench on the JAX
# Pendulum (Meta, paper preset, 64 seeds: whole training vs env alone vs updates alone) and det_ops_env.py
# (HalfCheetah on MJX, 512 envs, stepping alone). Outputs: det_ops_h200.log, det_ops_*.json/md, summary_cache*.json.
export PYTHONUNBUFFERED=1 MUJOCO_GL=disable XLA_PYTHON_CLIENT_PREALLOCATE=false
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
export PYTHONPATH=/tmp/site:$PWD JAX_PLATFORMS=cuda,cpu
unset XLA_FLAGS
L=$OUT/det_ops_h200.log
{ date -u; nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader; nproc
  python3 -c "import jax,flax,brax,mujoco,filelock;print('jax',jax.__version__,'flax',flax.__version__,'brax',brax.__version__,'mujoco',mujoco.__version__,'filelock',filelock.__version__);print(jax.devices())"
} 2>&1 | tee $L
for i in 1 2; do
  echo "=== compile cache, run $i $(date -u +%T)" | tee -a $L
  timeout 120 python3 -m experiments.run --env=pendulum --method=meta --seeds=8 --steps=1800 --set run.eval_every=900 \
    --compile-cache /tmp/cc --out /tmp/r/cache$i --quiet --no-plot 2>&1 | grep -v settotalmass | tail -n 4 | tee -a $L
  cp /tmp/r/cache$i/summary.json $OUT/summary_cache$i.json 2>/dev/null
done
for leg in default optout; do
  [ $leg = optout ] && export XLA_FLAGS=--xla_gpu_deterministic_ops=false
  echo "=== leg $leg: XLA_FLAGS=${XLA_FLAGS-unset} $(date -u +%T)" | tee -a $L
  timeout 150 python3 -m experiments.bench --envs pendulum --methods meta --presets paper --seeds 64 --repeats 3 \
    --target-steps 1000 --out $OUT/det_ops_bench_$leg.md --json $OUT/det_ops_bench_$leg.json 2>&1 | grep -v settotalmass | tail -n 3 | tee -a $L
  timeout 90 python3 results/benchmarks/gpu/scripts/det_ops_env.py 512 2>&1 | grep -v -i "settotalmass\|warp" | tee -a $L
done
echo "done $(date -u +%T)" | tee -a $L
