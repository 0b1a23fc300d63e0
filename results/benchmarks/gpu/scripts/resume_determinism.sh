#!/bin/bash
# GPU check (session 11): tests/test_longrun.py::test_sigkill_then_resume_gives_the_same_result (a run killed by
# SIGKILL and resumed in a new process vs the same run uninterrupted in the pytest process) on the GPU, two legs
# side by side, full output kept for each. This is the second call's version: the package now adds
# --xla_gpu_deterministic_ops=true to XLA_FLAGS on import, so the legs are XLA_FLAGS unset (that default) and the
# opt-out (=false). The first call, before that default existed, ran XLA_FLAGS unset (= XLA's defaults) and
# XLA_FLAGS=--xla_gpu_deterministic_ops=true: resume_call1_*.log.
export PYTHONUNBUFFERED=1 MUJOCO_GL=disable XLA_PYTHON_CLIENT_PREALLOCATE=false
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
export PYTHONPATH=/tmp/site:$PWD JAX_PLATFORMS=cuda,cpu
unset XLA_FLAGS
T=tests/test_longrun.py::test_sigkill_then_resume_gives_the_same_result
leg() {  # leg <name> [XLA_FLAGS value]
  ( [ $# -gt 1 ] && export XLA_FLAGS=$2
    timeout 200 python3 -m pytest -p no:cacheprovider -p no:benchmark -q -vv $T > $OUT/resume_call2_$1.log 2>&1
    echo "$1 (XLA_FLAGS=${XLA_FLAGS-unset}) rc=$?" >> $OUT/resume_call2_$1.log )
}
leg package_default & leg opt_out --xla_gpu_deterministic_ops=false & wait
tail -n 3 $OUT/resume_call2_*.log
